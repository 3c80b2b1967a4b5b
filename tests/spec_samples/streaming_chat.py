"""A streaming component written from architecture.md's "Streaming" section alone (issue 37).

Nothing here knows how the framework moves data: the component declares ``config.stream``, takes a
WebSocket client, puts its request through ``_call_inference`` (which, in that flow, queues it and
returns None), and its ``_handle_websocket_streaming`` reads partial results from
``self.resp_queue`` and publishes them with ``stream`` / ``done`` flags, token by token.
"""

from __future__ import annotations

import queue
from typing import Any

from agents_core.components.model_component import ModelComponent
from agents_core.config import LLMConfig
from agents_core.ros import StreamingString, String

#: What RoboML's WebSocket sends after the last token of a reply (the RoboML WS protocol).
RESPONSE_TERMINATOR = "<<Response Ended>>"


class StreamingChat(ModelComponent):
    """Answers each question on its String input token by token on a StreamingString output."""

    def __init__(self, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.handled_outputs = [StreamingString]
        self.tokens_seen = 0
        kwargs.setdefault("config", LLMConfig(stream=True))
        super().__init__(**kwargs)

    def _create_input(self, *args: Any, **kwargs: Any) -> dict[str, Any] | None:
        text = None
        for cb in self.trig_callbacks.values():
            text = cb.get_output()
        if not text:
            return None
        return {"query": [{"role": "user", "content": text}], **self.inference_params}

    def _execution_step(self, **kwargs: Any) -> None:
        inference_input = self._create_input()
        if inference_input is None:
            return
        result = self._call_inference(inference_input)
        if result is None:
            return  # streaming: the reply comes through resp_queue
        self._publish(result)

    def _warmup(self, *args: Any, **kwargs: Any) -> None:
        """Nothing to warm up for this example."""

    def _handle_websocket_streaming(self) -> Any:
        try:
            token = self.resp_queue.get_nowait()
        except queue.Empty:
            return None
        if token == RESPONSE_TERMINATOR:
            self._publish({"output": ""}, stream=True, done=True)
            return None
        self.tokens_seen += 1
        self._publish({"output": token}, stream=True, done=False)
        return None
