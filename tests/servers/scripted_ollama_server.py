"""An Ollama server double whose ``/api/chat`` replays scripted answers per request: Cortex's planner in recipes.

Upstream's Cortex recipes put the planner, the VLM and the embeddings on one Ollama server, often
on the same model. ``ScriptedOllamaServer`` is :class:`~tests.servers.ollama_server.OllamaTestServer`
(its models, ``/api/embed``, ``/api/generate``, streaming, faults) with ``/api/chat`` split three ways:

- *confirmations*: the first message is a system prompt starting with ``confirm_marker`` (Cortex's
  executor asks before each step); answered from ``confirm`` in order, then ``"EXECUTE"``;
- *planning*: any other request that offers ``tools``; answered from ``plan`` in order, then ``"done"``;
- everything else (a VLM caption, Memory's consolidation): the base server's answer
  (``reply``, else ``"You said: <last user message>"``).

Script entries are :mod:`tests.servers.scripted_chat_server`'s: ``text(...)``, ``calls(...)``,
``{"hang": seconds}`` or a callable of the request body. Tool-call arguments go out as a JSON
object, as Ollama sends them (a str is sent as it is, for malformed arguments). Every scripted
request body is kept (``planning_requests``, ``confirmation_requests``).
"""

from __future__ import annotations

import threading
from typing import Any

from .ollama_server import Fault, OllamaTestServer, ProtocolHandler, _now
from .scripted_chat_server import Entry, calls, text

__all__ = ["ScriptedOllamaServer", "calls", "text"]


class ScriptedOllamaServer(OllamaTestServer):
    """See the module docstring; ``models`` / ``reply`` are :class:`OllamaTestServer`'s."""

    def __init__(self, plan: list[Entry] | None = None, confirm: list[Entry] | None = None, *,
                 confirm_marker: str = "You supervise", models: list[str] | None = None,
                 reply: str | None = None) -> None:
        super().__init__(models=models, reply=reply)
        self.plan_script = list(plan or [])
        self.confirm_script = list(confirm or [])
        self.confirm_marker = confirm_marker
        self.planning_requests: list[dict[str, Any]] = []
        self.confirmation_requests: list[dict[str, Any]] = []
        self._script_lock = threading.Lock()

    def add_plan(self, *entries: Entry) -> None:
        """Append planner answers (for a later task of the same recipe run)."""
        with self._script_lock:
            self.plan_script.extend(entries)

    def add_confirmations(self, *entries: Entry) -> None:
        """Append confirmation answers."""
        with self._script_lock:
            self.confirm_script.extend(entries)

    def _scripted_entry(self, body: dict[str, Any]) -> Entry | None:
        """The entry answering ``body``, or None when the request is not the planner's."""
        messages = body.get("messages") or []
        first = messages[0] if messages and isinstance(messages[0], dict) else {}
        system = first.get("content", "") if first.get("role") == "system" else ""
        with self._script_lock:
            if isinstance(system, str) and system.startswith(self.confirm_marker):
                self.confirmation_requests.append(body)
                return self.confirm_script.pop(0) if self.confirm_script else text("EXECUTE")
            if body.get("tools"):
                self.planning_requests.append(body)
                return self.plan_script.pop(0) if self.plan_script else text("done")
        return None

    def _chat(self, handler: ProtocolHandler, body: dict[str, Any], fault: Fault | None) -> None:
        entry = self._scripted_entry(body) if isinstance(body.get("messages"), list) else None
        if entry is None or self._model_of(handler, body) is None:
            if entry is None:
                super()._chat(handler, body, fault)
            return
        if callable(entry):
            entry = entry(body)
        if "hang" in entry:
            self.wait_or_stop(float(entry["hang"]))
            handler.die()
            return
        message: dict[str, Any] = {"role": "assistant", "content": entry.get("text", "")}
        named = entry.get("calls") or []
        if named:
            message["tool_calls"] = [{"function": {"index": i, "name": name, "arguments": args}}
                                     for i, (name, args) in enumerate(named)]
        base = {"model": body.get("model"), "created_at": _now()}
        if body.get("stream") is False:
            handler.send_json(200, {**base, "message": message, "done_reason": "stop", "done": True,
                                    **self._stats(1)})
            return
        self._stream_lines(handler, [{**base, "message": message, "done": False},
                                     {**base, "message": {"role": "assistant", "content": ""},
                                      "done_reason": "stop", "done": True, **self._stats(1)}], fault)
