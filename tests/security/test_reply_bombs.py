"""Hostile model servers: a small gzip body inflating to 200 MiB, endless split or streamed replies.

Every HTTP/WebSocket model client (OpenAI-compatible, Ollama, RoboML over HTTP and WebSocket)
stops reading at its ``max_reply_bytes`` (counted after decompression, streams included) with an
error naming the server and the limit, and its memory stays far below what the bomb inflates to.
The servers are real: a ``ThreadingHTTPServer`` and a ``websockets`` server on 127.0.0.1.
"""

from __future__ import annotations

import contextlib
import resource
import threading
import time
import zlib
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import pytest

from agents_core.clients import GenericHTTPClient, OllamaClient, RoboMLHTTPClient, RoboMLWSClient
from agents_core.clients.roboml_protocol import WS_CHUNK_SIZE
from agents_core.errors import ConfigError, ModelClientError
from agents_core.models import GenericLLM, OllamaModel, TransformersLLM

pytestmark = pytest.mark.timeout(120)

INFLATED = 200 * 1024 * 1024
LIMIT = 1024 * 1024


def _bomb(unit: bytes, total: int = INFLATED, wbits: int = 31) -> bytes:
    """``unit`` repeated to ``total`` bytes, compressed (gzip by default) a piece at a time."""
    comp = zlib.compressobj(9, zlib.DEFLATED, wbits)
    piece = unit * (1024 * 1024 // len(unit))
    out = [comp.compress(piece) for _ in range(total // len(piece))]
    return b"".join(out) + comp.flush()


@pytest.fixture(scope="module")
def bombs() -> dict[str, bytes]:
    sse = b'data: {"choices": [{"delta": {"content": "aaaaaaaaaaaaaaaa"}}]}\n\n'
    nd = b'{"message": {"content": "aaaaaaaaaaaaaaaa"}, "done": false}\n'
    return {"json": _bomb(b" "), "sse": _bomb(sse), "ndjson": _bomb(nd), "text": _bomb(b"a"),
            "deflate": _bomb(b" ", wbits=15)}


class _BombServer:
    """Answers every POST with one of ``bombs`` (picked by path), ``Content-Encoding`` set to match."""

    def __init__(self, bombs: dict[str, bytes]) -> None:
        owner = self
        self.requests: list[str] = []

        class Handler(BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.1"

            def do_POST(self) -> None:
                self.rfile.read(int(self.headers.get("Content-Length", "0")))
                owner.requests.append(self.path)
                if self.path.endswith("/chat/completions"):
                    body, kind = ((bombs["sse"], "text/event-stream") if owner.stream
                                  else (bombs["json"], "application/json"))
                elif self.path == "/api/chat":
                    body, kind = (bombs["ndjson"], "application/x-ndjson") if owner.stream else (bombs["json"],
                                                                                               "application/json")
                else:
                    body, kind = (bombs["text"], "text/plain") if owner.stream else (bombs["json"], "application/json")
                encoding = "gzip"
                if owner.deflate and not owner.stream:
                    body, encoding = bombs["deflate"], "deflate"
                self.send_response(200)
                self.send_header("Content-Type", kind)
                self.send_header("Content-Encoding", encoding)
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                with contextlib.suppress(OSError):  # the client stopped reading: what we want
                    self.wfile.write(body)

            def log_message(self, format: str, *args: object) -> None:
                pass

        self.stream = False
        self.deflate = False
        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.httpd.daemon_threads = True
        self.httpd.handle_error = lambda *_: None  # type: ignore[method-assign]  # a client that hung up
        self.port = self.httpd.server_address[1]
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self.thread.start()

    def close(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()
        self.thread.join(5)


@pytest.fixture
def server(bombs: dict[str, bytes]) -> Iterator[_BombServer]:
    srv = _BombServer(bombs)
    yield srv
    srv.close()


def _maxrss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _chat(stream: bool) -> dict[str, Any]:
    return {"query": [{"role": "user", "content": "hi"}], "stream": stream}


def _refused(call: Any, port: int) -> tuple[str, float, float]:
    """Run ``call``: it must raise the typed error; returns (message, seconds, RSS high-water growth)."""
    before = _maxrss_mb()
    start = time.monotonic()
    with pytest.raises(ModelClientError) as info:
        out = call()
        if not isinstance(out, str | dict):  # a stream: read it to the end
            for _ in out:
                pass
    message = str(info.value)
    assert "max_reply_bytes" in message and str(LIMIT) in message, message
    assert f"127.0.0.1:{port}" in message, message
    seconds, grown = time.monotonic() - start, _maxrss_mb() - before
    print(f"refused in {seconds:.2f} s, RSS high-water +{grown:.0f} MB: {message[:160]}")
    return message, seconds, grown


@pytest.mark.parametrize("stream", [False, True])
def test_openai_compatible_client_refuses_a_gzip_bomb(server: _BombServer, stream: bool) -> None:
    server.stream = stream
    client = GenericHTTPClient(GenericLLM(name="llm", checkpoint="m"), port=server.port, max_reply_bytes=LIMIT)
    try:
        _, seconds, grown = _refused(lambda: client.inference(_chat(stream))["output"], server.port)
    finally:
        client.close()
    assert grown < 100, f"RSS grew {grown:.0f} MB for a reply bounded at 1 MiB"
    assert seconds < 10


@pytest.mark.parametrize("stream", [False, True])
def test_ollama_client_refuses_a_gzip_bomb(server: _BombServer, stream: bool) -> None:
    server.stream = stream
    client = OllamaClient(OllamaModel(name="llm", checkpoint="m"), port=server.port, max_reply_bytes=LIMIT)
    try:
        _, _, grown = _refused(lambda: client.inference(_chat(stream))["output"], server.port)
    finally:
        client.close()
    assert grown < 100


@pytest.mark.parametrize("stream", [False, True])
def test_roboml_http_client_refuses_a_gzip_bomb(server: _BombServer, stream: bool) -> None:
    server.stream = stream
    client = RoboMLHTTPClient(TransformersLLM(name="llm"), port=server.port, max_reply_bytes=LIMIT)
    try:
        _, _, grown = _refused(lambda: client.inference(_chat(stream))["output"], server.port)
    finally:
        client.close()
    assert grown < 100


def test_a_deflate_bomb_is_refused_too(server: _BombServer) -> None:
    server.deflate = True
    client = GenericHTTPClient(GenericLLM(name="llm", checkpoint="m"), port=server.port, max_reply_bytes=LIMIT)
    try:
        _refused(lambda: client.inference(_chat(False))["output"], server.port)
    finally:
        client.close()


def test_a_reply_within_the_limit_still_reads(server: _BombServer) -> None:
    # The same bomb under a limit above its size is read whole: the bound does not break gzip.
    client = GenericHTTPClient(GenericLLM(name="llm", checkpoint="m"), port=server.port,
                               max_reply_bytes=INFLATED + 1024)
    try:
        with pytest.raises(ModelClientError, match=r"choices|not JSON|message"):
            client.inference(_chat(False))  # 200 MiB of spaces is not an answer, but it was read
    finally:
        client.close()


def test_the_limit_is_checked_and_serialized() -> None:
    with pytest.raises(ConfigError, match="max_reply_bytes"):
        GenericHTTPClient(GenericLLM(name="llm", checkpoint="m"), max_reply_bytes=0)
    with pytest.raises(ConfigError, match="max_reply_bytes"):
        OllamaClient(OllamaModel(name="llm", checkpoint="m"), max_reply_bytes=True)  # type: ignore[arg-type]
    spec = GenericHTTPClient(GenericLLM(name="llm", checkpoint="m"), max_reply_bytes=12345).serialize()
    assert spec["max_reply_bytes"] == 12345


# -- RoboML over WebSocket ----------------------------------------------------------------------------


class _WSBomb:
    """A websockets server at ``/<node>/ws_inference`` sending endless 1 MiB pieces of a "split" reply,
    or an endless token stream (never the end marker)."""

    def __init__(self) -> None:
        from websockets.sync.server import serve  # noqa: PLC0415

        self.mode = "split"
        self.stop = threading.Event()

        def handler(ws: Any) -> None:
            ws.recv()
            try:
                while not self.stop.is_set():
                    if self.mode == "split":
                        ws.send(b"\x00" * WS_CHUNK_SIZE)
                    else:
                        ws.send("token " * 1000)
            except Exception:  # the client went away
                return

        self.server = serve(handler, "127.0.0.1", 0, max_size=None, compression=None)
        self.port = self.server.socket.getsockname()[1]
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()

    def close(self) -> None:
        self.stop.set()
        self.server.shutdown()
        self.thread.join(5)


@pytest.mark.parametrize("mode", ["split", "stream"])
def test_roboml_ws_client_bounds_split_and_streamed_replies(mode: str) -> None:
    srv = _WSBomb()
    srv.mode = mode
    client = RoboMLWSClient(TransformersLLM(name="llm"), port=srv.port, inference_timeout=30,
                            max_reply_bytes=4 * LIMIT)
    try:
        before = _maxrss_mb()
        with pytest.raises(ModelClientError) as info:
            out = client.inference(_chat(mode == "stream"))["output"]
            for _ in out:
                pass
        assert "max_reply_bytes" in str(info.value) and str(4 * LIMIT) in str(info.value), info.value
        assert f"127.0.0.1:{srv.port}" in str(info.value)
        assert _maxrss_mb() - before < 200
    finally:
        client.close()
        srv.close()
