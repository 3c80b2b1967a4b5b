"""The shared HTTP plumbing of the clients (clients/http_base.py) against a real local HTTP server.

The server writes each body in pieces, split inside lines and events on purpose, the way a
proxy or a slow model delivers them; the helpers must put the pieces back together.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import httpx
import pytest

from agents_core.clients import GenericHTTPClient, OllamaClient
from agents_core.clients.http_base import (
    check_response,
    iter_ndjson,
    server_error_message,
    sse_data,
)
from agents_core.clients.roboml_protocol import ROBOML_NODE_MODELS
from agents_core.errors import ConfigError, HTTPStatusError, ProtocolError
from agents_core.models import GenericLLM, GenericSTT, GenericTTS, Model, VisionModel, Whisper

#: path -> (status, content type, the body's pieces, written one by one).
BODIES: dict[str, tuple[int, str, list[bytes]]] = {
    "/ndjson": (200, "application/x-ndjson",
                [b'{"a": 1}\n\n{"b"', b': 2}\n', b"   \n", b'{"c": [3]}\n']),
    "/ndjson-bad": (200, "application/x-ndjson", [b'{"a": 1}\n', b"[1, 2]\n"]),
    "/sse": (200, "text/event-stream; charset=utf-8",
             [b": keep-alive\n\n", b"data: one\n", b"\ndata: two\r\ndata: lines\r\n\r\n", b"event: ping\n\n",
              b"id: 7\nretry: 100\n\n", b"data: [DONE]\n\n"]),
    "/not-sse": (200, "application/json", [b'{"choices": []}']),
    "/chroma-error": (400, "application/json", [b'{"error": "InvalidArgumentError", "message": "bad name"}']),
    "/openai-error": (401, "application/json", [b'{"error": {"message": "Incorrect API key", "code": 401}}']),
    "/ollama-error": (404, "application/json", [b'{"error": "model not found"}']),
    "/fastapi-error": (422, "application/json", [b'{"detail": [{"loc": ["query"], "msg": "required"}]}']),
    "/text-error": (500, "text/plain", [b"it broke"]),
}


class _Handler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.0"  # the body ends when the connection closes: no length needed

    def do_GET(self) -> None:
        status, content_type, pieces = BODIES[self.path]
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.end_headers()
        for piece in pieces:
            self.wfile.write(piece)
            self.wfile.flush()
            time.sleep(0.01)  # separate reads on the client side

    def log_message(self, format: str, *args: object) -> None:  # quiet: pytest shows failures
        pass


@pytest.fixture(scope="module")
def base_url() -> Iterator[str]:
    server = ThreadingHTTPServer(("127.0.0.1", 0), _Handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


@contextmanager
def _streamed(base_url: str, path: str) -> Iterator[httpx.Response]:
    with httpx.Client(base_url=base_url, timeout=5) as client, client.stream("GET", path) as response:
        yield response


def test_ndjson_lines_become_objects(base_url: str) -> None:
    with _streamed(base_url, "/ndjson") as response:
        assert list(iter_ndjson(response.iter_lines(), "ctx")) == [{"a": 1}, {"b": 2}, {"c": [3]}]
    with _streamed(base_url, "/ndjson-bad") as response:
        objects = iter_ndjson(response.iter_lines(), "ctx")
        assert next(objects) == {"a": 1}
        with pytest.raises(ProtocolError, match=r"ctx: a streamed line is not a JSON object: '\[1, 2\]'"):
            next(objects)


def test_sse_events_give_their_data_and_skip_the_rest(base_url: str) -> None:
    with _streamed(base_url, "/sse") as response:
        # The keep-alive comment, the data-less ping and the id/retry-only event yield nothing.
        assert list(sse_data(response, "ctx")) == ["one", "two\nlines", "[DONE]"]
    with _streamed(base_url, "/not-sse") as response, pytest.raises(ProtocolError, match="ctx: not an event stream"):
        list(sse_data(response, "ctx"))


@pytest.mark.parametrize(("path", "message"), [
    ("/chroma-error", "InvalidArgumentError: bad name"),
    ("/openai-error", "Incorrect API key"),
    ("/ollama-error", "model not found"),
    ("/fastapi-error", '[{"loc": ["query"], "msg": "required"}]'),
    ("/text-error", "it broke"),
])
def test_error_bodies_give_the_server_message(base_url: str, path: str, message: str) -> None:
    # Streamed, so the error body is read by the helper itself.
    with _streamed(base_url, path) as response:
        assert server_error_message(response) == message
        with pytest.raises(HTTPStatusError, match=f"^ctx: it answered {response.status_code}: ") as info:
            check_response(response, "ctx", "it answered {status}")
        assert info.value.status == response.status_code


def test_each_model_class_declares_its_task_once() -> None:
    assert [m.task for m in (Model, GenericLLM, GenericTTS, GenericSTT, Whisper, VisionModel)] \
        == ["chat", "chat", "text_to_speech", "speech_to_text", "speech_to_text", "detection"]
    assert ROBOML_NODE_MODELS["Whisper"] == "speech_to_text" and ROBOML_NODE_MODELS["VisionModel"] == "detection"
    client = GenericHTTPClient(GenericSTT(name="stt", checkpoint="whisper-1"))
    assert client.task == "speech_to_text" and client.kind == "stt"
    # A model type this process does not know is served as a chat model, as before.
    spec = client.serialize()
    spec["model"]["model_type"] = "SomeoneElsesModel"
    assert GenericHTTPClient(spec["model"]).task == "chat"
    # A client refuses a model whose task it has no handler for, when it is built.
    with pytest.raises(ConfigError, match=r"'detection' model; this client serves \['chat'"):
        GenericHTTPClient(VisionModel(name="eyes"))
    with pytest.raises(ConfigError, match="'speech_to_text' model"):
        OllamaClient(Whisper(name="ears"))
