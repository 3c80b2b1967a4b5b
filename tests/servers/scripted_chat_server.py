"""An OpenAI-compatible chat server that replays scripted answers: the planner model of Cortex tests.

``ScriptedChatServer`` answers ``GET /v1/models`` and ``POST /v1/chat/completions`` on 127.0.0.1
(a free port). Requests are split in two queues by their system prompt: *confirmations* (the
system prompt starts with ``confirm_marker``) and *planning* (every other). Each queue answers
from its script in order; an entry is

- ``{"text": "..."}``: an answer without tool calls;
- ``{"calls": [(name, arguments), ...], "text": ""}``: tool calls (arguments sent as a JSON string,
  as OpenAI does; a str is sent as it is, for malformed arguments);
- ``{"hang": seconds}``: read the request and answer nothing for that long;
- a callable taking the request body and returning one of the above.

When a script runs out the planner answers ``"done"`` and the confirmation ``"EXECUTE"``. Every
request body is kept (``planning_requests``, ``confirmation_requests``).
"""

from __future__ import annotations

import json
import threading
from collections.abc import Callable
from typing import Any

from .ollama_server import Fault, ProtocolHandler, ProtocolServer, RecordedRequest

__all__ = ["ScriptedChatServer", "calls", "text"]

Entry = dict[str, Any] | Callable[[dict[str, Any]], dict[str, Any]]


def text(answer: str) -> dict[str, Any]:
    """A script entry answering ``answer`` without tool calls."""
    return {"text": answer}


def calls(*named: tuple[str, Any], answer: str = "") -> dict[str, Any]:
    """A script entry calling the tools ``(name, arguments)`` in order."""
    return {"calls": list(named), "text": answer}


class ScriptedChatServer(ProtocolServer):
    """See the module docstring."""

    def __init__(self, plan: list[Entry] | None = None, confirm: list[Entry] | None = None,
                 confirm_marker: str = "You supervise", model: str = "planner") -> None:
        super().__init__()
        self.plan_script = list(plan or [])
        self.confirm_script = list(confirm or [])
        self.confirm_marker = confirm_marker
        self.model = model
        self.planning_requests: list[dict[str, Any]] = []
        self.confirmation_requests: list[dict[str, Any]] = []
        self._script_lock = threading.Lock()

    def error_body(self, message: str) -> Any:
        return {"error": {"message": message, "type": "server_error"}}

    def route(self, handler: ProtocolHandler, request: RecordedRequest, fault: Fault | None) -> None:
        if request.method == "GET" and request.path == "/v1/models":
            handler.send_json(200, {"object": "list", "data": [{"id": self.model, "object": "model"}]})
            return
        if request.method != "POST" or request.path != "/v1/chat/completions" or not isinstance(request.json, dict):
            handler.send_json(404, self.error_body("not found"))
            return
        body = request.json
        messages = body.get("messages") or []
        system = messages[0].get("content", "") if messages and isinstance(messages[0], dict) else ""
        confirming = isinstance(system, str) and system.startswith(self.confirm_marker)
        with self._script_lock:
            if confirming:
                self.confirmation_requests.append(body)
                entry: Entry = self.confirm_script.pop(0) if self.confirm_script else text("EXECUTE")
            else:
                self.planning_requests.append(body)
                entry = self.plan_script.pop(0) if self.plan_script else text("done")
        if callable(entry):
            entry = entry(body)
        if "hang" in entry:
            self.wait_or_stop(float(entry["hang"]))
            handler.die()
            return
        message: dict[str, Any] = {"role": "assistant", "content": entry.get("text", "")}
        named = entry.get("calls") or []
        if named:
            message["tool_calls"] = [
                {"id": f"call_{len(self.planning_requests)}_{len(self.confirmation_requests)}_{i}", "type": "function",
                 "function": {"name": name, "arguments": args if isinstance(args, str) else json.dumps(args)}}
                for i, (name, args) in enumerate(named)]
        handler.send_json(200, {"id": "chatcmpl-scripted", "object": "chat.completion", "model": self.model,
                                "choices": [{"index": 0, "message": message,
                                             "finish_reason": "tool_calls" if named else "stop"}],
                                "usage": {"prompt_tokens": 10, "completion_tokens": 5, "total_tokens": 15}})
