"""architecture.md, "Streaming", end to end: a component written from the text against a real WebSocket server.

The server is the RoboML double (tests/servers/roboml_server.py: RoboML 0.6.1's HTTP and WebSocket
protocols on 127.0.0.1). The component (streaming_chat.py) only follows the text: config.stream,
a RoboMLWSClient, ``_call_inference`` then ``_handle_websocket_streaming`` reading
``self.resp_queue``. What the text says happens is checked: the fast loop is set up at configure,
the request goes through ``req_queue`` and the WebSocket, and the tokens arrive one by one and are
published incrementally, on the memory transport and across two Zenoh sessions.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator
from typing import Any

import pytest

from agents_core import Launcher, Topic
from agents_core.clients import RoboMLWSClient
from agents_core.messages import StreamingStringMsg
from agents_core.models import TransformersLLM
from agents_core.testing.pairs import memory_pair, skip_unless_installed, zenoh_pair
from agents_core.transport.contract import Transport

from ..conftest import wait_for
from ..servers.roboml_server import RoboMLTestServer
from .streaming_chat import StreamingChat

QUESTION, ANSWER = Topic("question", "String"), Topic("answer", "StreamingString")


@contextlib.contextmanager
def _pair(name: str) -> Iterator[tuple[Transport, Transport]]:
    if name == "zenoh":
        skip_unless_installed("zenoh", "zenoh")
        with zenoh_pair() as pair:
            yield pair
    else:
        with memory_pair() as pair:
            yield pair


def _client(server: RoboMLTestServer) -> RoboMLWSClient:
    return RoboMLWSClient(TransformersLLM(name="chat", checkpoint="some/llm"), port=server.port, inference_timeout=10)


@pytest.mark.parametrize("transport", ["memory", "zenoh"])
def test_a_component_written_from_the_streaming_section_streams_token_by_token(transport: str) -> None:
    with RoboMLTestServer() as server, _pair(transport) as (here, there):
        chat = StreamingChat(inputs=[QUESTION], outputs=[ANSWER], model_client=_client(server), trigger=QUESTION,
                             component_name="streaming_chat")
        chunks: list[StreamingStringMsg] = []
        done = threading.Event()

        def on_chunk(msg: StreamingStringMsg) -> None:
            chunks.append(msg)
            if msg.done:
                done.set()

        launcher = Launcher(here)
        launcher.add_pkg(components=[chat])
        with launcher:
            # "A fast timer ... is created" at configure: the loops run before any request.
            assert chat._ws_streaming.running
            sub = there.create_subscription(ANSWER, on_chunk)
            pub = there.create_publisher(QUESTION)
            for _ in range(5):  # across Zenoh sessions the first sample may precede discovery
                pub.publish("where is the red cube")
                if wait_for(lambda: bool(chunks), timeout=5):
                    break
            assert done.wait(20), f"no final chunk; got {chunks}"
            sub.close()
            pub.close()
        first: list[StreamingStringMsg] = []
        for chunk in chunks:
            first.append(chunk)
            if chunk.done:
                break
        # Token by token: one chunk per word the server streamed, flagged stream=True, done on the last.
        assert "".join(c.data for c in first) == "echo: where is the red cube"
        assert len(first) == 7 and all(c.stream for c in first)
        assert [c.done for c in first] == [False] * 6 + [True]
        ws_calls = server.calls_of("inference", "ws")
        assert ws_calls and ws_calls[0].payload["stream"] is True, "the request went over the WebSocket"
        assert chat._ws_streaming.served >= 1 and chat.tokens_seen >= 6


def test_the_request_goes_into_req_queue_and_call_inference_returns_none() -> None:
    with RoboMLTestServer() as server:
        chat = StreamingChat(inputs=[QUESTION], outputs=[ANSWER], model_client=_client(server), trigger=QUESTION)
        chat.configure()
        try:
            # "custom_on_configure() detects config.stream with a RoboMLWSClient": the loops run after
            # configure alone, before activate; the fast loop calls the hook only while active.
            assert chat._ws_streaming.running and chat.lifecycle_state.value == "inactive"
            chat._ws_streaming.stop()  # hold the client loop: look at the queue itself
            chat._ws_streaming._threads = [threading.Thread(target=lambda: None)]  # "running", loops parked
            assert chat._call_inference({"query": [{"role": "user", "content": "hi"}]}) is None
            request: dict[str, Any] = chat.req_queue.get_nowait()
            assert request["query"][-1]["content"] == "hi" and request["stream"] is True
            chat._ws_streaming._threads = []
        finally:
            chat.shutdown()
