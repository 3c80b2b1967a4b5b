"""A chat model client that answers from a script: the test double for LLM / MLLM / router tests.

It follows the payload contract of :mod:`agents_core.clients.payloads` (the same one the real
clients implement), records every inference input as it was at call time, and streams a reply
given as a list of chunks when the input asks for streaming.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, MutableMapping
from typing import Any

from agents_core.clients import ModelClient
from agents_core.clients.payloads import ChunkStream
from agents_core.errors import ClientConnectionError
from agents_core.models import GenericLLM

Reply = str | list[str] | dict[str, Any] | Callable[[dict[str, Any]], Any]


class ScriptedChatClient(ModelClient):
    """Answers with ``script`` entries in order (the last one repeats).

    An entry is a str (the answer), a list of str (chunks: streamed when asked, else joined), a
    dict (returned as the result, e.g. with ``tool_calls``) or a callable taking the input.
    ``fail=True`` makes every inference fail as an unreachable server would.
    """

    def __init__(self, script: list[Reply] | None = None, fail: bool = False, tools: bool = True,
                 **kwargs: Any) -> None:
        kwargs.setdefault("model", GenericLLM(name="scripted", checkpoint="scripted-model"))
        super().__init__(**kwargs)
        self.script = list(script or ["ok"])
        self.fail = fail
        self.tools = tools
        self.inputs: list[dict[str, Any]] = []
        self.streams: list[ChunkStream[str]] = []

    @property
    def supports_tool_calls(self) -> bool:
        return self.tools

    def _check_connection(self) -> None:
        pass

    def _initialize(self) -> None:
        pass

    def _deinitialize(self) -> None:
        pass

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        if self.fail:
            raise ClientConnectionError("scripted client: the server is down")
        # The component keeps appending to its message list: record what was sent at this moment.
        self.inputs.append(copy.deepcopy(inference_input))
        entry = self.script[min(len(self.inputs) - 1, len(self.script) - 1)]
        if callable(entry):
            entry = entry(inference_input)
        if isinstance(entry, dict):
            return dict(entry)
        if isinstance(entry, list):
            if inference_input.get("stream") and not inference_input.get("tools"):
                stream = ChunkStream(iter(list(entry)), label="scripted")
                self.streams.append(stream)
                return {"output": stream}
            return {"output": "".join(entry)}
        return {"output": str(entry)}


def tool_call(name: str, arguments: dict[str, Any], call_id: str) -> dict[str, Any]:
    """A reply in which the model calls one tool."""
    return {"output": "", "tool_calls": [{"id": call_id, "type": "function",
                                          "function": {"name": name, "arguments": arguments}}]}
