"""A model server that fails on purpose: slow, stalled, cut, malformed or leaking the caller's key.

``FaultServer`` listens on 127.0.0.1 (a free port) in a background thread, built on the
:class:`~tests.servers.ollama_server.ProtocolServer` plumbing. It speaks both model protocols the
deadline tests need: the OpenAI API (``GET /v1/models``, ``POST /v1/chat/completions``, JSON or
server-sent events) and Ollama's (``GET /api/version``, ``POST /api/show``, ``POST /api/generate``,
``POST /api/chat``, JSON or NDJSON). The chat endpoints answer according to :attr:`FaultServer.mode`:

``"ok"``                      a normal answer (the streamed one as pieces).
``"keepalive"``               200, then keep-alive forever: SSE comments ``": ping"`` for the OpenAI
                              stream, blank lines for NDJSON, whitespace for a JSON answer (what
                              OpenAI sends before a slow non-streamed answer); never an answer.
``"trickle"``                 the correct answer, one byte every ``interval`` seconds.
``"trickle_until_close"``     the same with no Content-Length or chunking: the body ends when the
                              connection closes (HTTP/1.0 style), so a cut looks like its end.
``"headers_then_stall"``      status and headers, then nothing.
``"stall_before_headers"``    reads the request, then sends nothing.
``"first_chunk_then_stall"``  status, headers and the first piece of the answer, then nothing.
``"slow_chunks"``             a correct stream whose pieces come ``interval`` seconds apart.
``"echo_auth"``               401 with an error message quoting the ``Authorization`` header.
``"echo_auth_base64"``        401 quoting the key base64-encoded: as an HTTP Basic credential
                              (``user:key``) and as the bare URL-safe base64 of the key.
``"key_in_json_500"``         500 with a JSON error body holding the bare key.
``"key_mid_stream"``          200, one piece, then the protocol's mid-stream error quoting the key.
``"malformed_json"``          200 with a body that is not JSON (for a stream: an event that is not).
``"reset_midway"``            part of the answer, then a TCP reset.

Stalls last at most ``stall_seconds`` and end when the server stops, so no handler thread
outlives a test for long. Every request is recorded (``requests``, ``requests_to``), headers
included, so tests can check what a client sent.

Usage::

    with FaultServer(mode="keepalive") as server:
        client = GenericHTTPClient(GenericLLM(name="m", checkpoint="m"), port=server.port, inference_timeout=1)
        ...
        server.mode = "ok"
"""

from __future__ import annotations

import base64
import contextlib
import json
import socket
import struct
import time
from dataclasses import dataclass
from typing import Any

from .ollama_server import Fault, ProtocolHandler, ProtocolServer, RecordedRequest

__all__ = ["MODES", "FaultServer"]

MODES = ("ok", "keepalive", "trickle", "trickle_until_close", "headers_then_stall", "stall_before_headers",
         "first_chunk_then_stall", "slow_chunks", "echo_auth", "echo_auth_base64", "key_in_json_500", "key_mid_stream",
         "malformed_json", "reset_midway")

_CHAT_PATHS = {"/v1/chat/completions": "openai", "/api/chat": "ollama", "/api/generate": "ollama"}


class FaultServer(ProtocolServer):
    """An OpenAI + Ollama double whose chat endpoints misbehave as :attr:`mode` says.

    :param mode: one of :data:`MODES` (may be changed while serving).
    :param reply: the answer's text; it is streamed as its words.
    :param interval: seconds between bytes (``"trickle"``), keep-alives (``"keepalive"``) and
        pieces (``"slow_chunks"``).
    :param stall_seconds: the longest a stalling handler waits before giving up.
    """

    def __init__(self, mode: str = "ok", reply: str = "Hello there, robot friend.", interval: float = 1.0,
                 stall_seconds: float = 30.0) -> None:
        super().__init__()
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        self.mode = mode
        self.reply = reply
        self.interval = interval
        self.stall_seconds = stall_seconds

    def error_body(self, message: str) -> Any:
        return {"error": {"message": message}}

    # -- routing ------------------------------------------------------------------------------------

    def route(self, handler: ProtocolHandler, request: RecordedRequest, fault: Fault | None) -> None:
        path = request.path
        if path == "/v1/models":
            handler.send_json(200, {"object": "list", "data": [{"id": "m", "object": "model"}]})
        elif path == "/api/version":
            handler.send_json(200, {"version": "0.6.5"})
        elif path == "/api/show":
            handler.send_json(200, {"modelfile": "", "details": {"family": "llama"}})
        elif path == "/api/generate" and not (request.json or {}).get("prompt"):
            # Ollama's load / unload request.
            handler.send_json(200, {"model": "m", "response": "", "done": True, "done_reason": "load"})
        elif path in _CHAT_PATHS:
            body = request.json if isinstance(request.json, dict) else {}
            protocol = _CHAT_PATHS[path]
            # OpenAI streams only when asked; Ollama streams unless told not to.
            stream = bool(body.get("stream")) if protocol == "openai" else body.get("stream") is not False
            self._chat(handler, request, protocol, stream)
        else:
            handler.send_json(404, self.error_body(f"no route {path}"))

    # -- answers ------------------------------------------------------------------------------------

    def _pieces(self) -> list[str]:
        words = self.reply.split(" ")
        return [w + (" " if i < len(words) - 1 else "") for i, w in enumerate(words)]

    def _stream_events(self, protocol: str) -> list[bytes]:
        """The whole correct stream, one item per piece of the answer (the closing ones last)."""
        if protocol == "openai":
            events = [b"data: " + json.dumps({"choices": [{"index": 0, "delta": {"content": p},
                                                           "finish_reason": None}]}).encode() + b"\n\n"
                      for p in self._pieces()]
            events.append(b"data: " + json.dumps({"choices": [{"index": 0, "delta": {},
                                                               "finish_reason": "stop"}]}).encode() + b"\n\n")
            events.append(b"data: [DONE]\n\n")
            return events
        lines = [json.dumps({"model": "m", "message": {"role": "assistant", "content": p}, "response": p,
                             "done": False}).encode() + b"\n" for p in self._pieces()]
        lines.append(json.dumps({"model": "m", "message": {"role": "assistant", "content": ""}, "response": "",
                                 "done": True, "done_reason": "stop"}).encode() + b"\n")
        return lines

    def _whole_answer(self, protocol: str) -> bytes:
        if protocol == "openai":
            choice = {"index": 0, "message": {"role": "assistant", "content": self.reply}, "finish_reason": "stop"}
            return json.dumps({"id": "chatcmpl-1", "object": "chat.completion", "choices": [choice]}).encode()
        return json.dumps({"model": "m", "message": {"role": "assistant", "content": self.reply},
                           "response": self.reply, "done": True, "done_reason": "stop"}).encode()

    @staticmethod
    def _content_type(protocol: str, stream: bool) -> str:
        if not stream:
            return "application/json"
        return "text/event-stream" if protocol == "openai" else "application/x-ndjson"

    def _stall(self) -> None:
        self.wait_or_stop(self.stall_seconds)

    def _chat(self, handler: ProtocolHandler, request: RecordedRequest, protocol: str, stream: bool) -> None:
        authorization = request.headers.get("authorization", "")
        key = authorization.split(" ", 1)[1] if " " in authorization else authorization
        answer = _Answer(handler, protocol, stream, self._content_type(protocol, stream), authorization,
                         key or request.headers.get("x-chroma-token", ""))
        getattr(self, f"_{self.mode}")(answer)

    def _send_headers(self, answer: _Answer, length: int) -> None:
        handler = answer.handler
        handler.send_response(200)
        handler.send_header("Content-Type", answer.content_type)
        handler.send_header("Content-Length", str(length))
        handler.end_headers()
        handler.wfile.flush()

    def _ok(self, answer: _Answer) -> None:
        if answer.stream:
            answer.handler.start_stream(answer.content_type)
            for event in self._stream_events(answer.protocol):
                answer.handler.write_chunk(event)
            answer.handler.end_stream()
        else:
            answer.handler.send_bytes(200, self._whole_answer(answer.protocol), answer.content_type)

    def _keepalive(self, answer: _Answer) -> None:
        answer.handler.start_stream(answer.content_type)
        ping = b": ping\n\n" if answer.stream and answer.protocol == "openai" else b"\n"
        deadline = time.monotonic() + self.stall_seconds
        while time.monotonic() < deadline:
            answer.handler.write_chunk(ping)
            if self.wait_or_stop(self.interval):
                break
        answer.handler.close_connection = True

    def _trickle(self, answer: _Answer) -> None:
        data = b"".join(self._stream_events(answer.protocol)) if answer.stream else self._whole_answer(answer.protocol)
        self._send_headers(answer, len(data))
        for index in range(len(data)):
            answer.handler.wfile.write(data[index:index + 1])
            answer.handler.wfile.flush()
            if self.wait_or_stop(self.interval):
                break
        answer.handler.close_connection = True

    def _trickle_until_close(self, answer: _Answer) -> None:
        data = b"".join(self._stream_events(answer.protocol)) if answer.stream else self._whole_answer(answer.protocol)
        handler = answer.handler
        handler.send_response(200)
        handler.send_header("Content-Type", answer.content_type)
        handler.send_header("Connection", "close")
        handler.end_headers()
        handler.wfile.flush()
        for index in range(len(data)):
            try:
                handler.wfile.write(data[index:index + 1])
                handler.wfile.flush()
            except OSError:  # the client cut the connection
                break
            if self.wait_or_stop(self.interval):
                break
        handler.close_connection = True

    def _headers_then_stall(self, answer: _Answer) -> None:
        if answer.stream:
            answer.handler.start_stream(answer.content_type)
        else:
            self._send_headers(answer, len(self._whole_answer(answer.protocol)))
        self._stall()
        answer.handler.close_connection = True

    def _stall_before_headers(self, answer: _Answer) -> None:
        self._stall()
        answer.handler.close_connection = True

    def _first_part(self, answer: _Answer) -> None:
        """Headers and the first piece of the answer (half the body when not streamed)."""
        if answer.stream:
            answer.handler.start_stream(answer.content_type)
            answer.handler.write_chunk(self._stream_events(answer.protocol)[0])
        else:
            data = self._whole_answer(answer.protocol)
            self._send_headers(answer, len(data))
            answer.handler.wfile.write(data[:len(data) // 2])
            answer.handler.wfile.flush()

    def _first_chunk_then_stall(self, answer: _Answer) -> None:
        self._first_part(answer)
        self._stall()
        answer.handler.close_connection = True

    def _slow_chunks(self, answer: _Answer) -> None:
        if not answer.stream:
            self.wait_or_stop(self.interval * len(self._pieces()))
            answer.handler.send_bytes(200, self._whole_answer(answer.protocol), answer.content_type)
            return
        answer.handler.start_stream(answer.content_type)
        for event in self._stream_events(answer.protocol):
            answer.handler.write_chunk(event)
            if self.wait_or_stop(self.interval):
                break
        answer.handler.end_stream()

    def _echo_auth(self, answer: _Answer) -> None:
        message = f"Invalid credentials: the header was 'Authorization: {answer.authorization}'"
        answer.handler.send_json(401, {"error": {"message": message}} if answer.protocol == "openai"
                                 else {"error": message})

    def _echo_auth_base64(self, answer: _Answer) -> None:
        basic = base64.b64encode(f"robot:{answer.key}".encode()).decode()
        bare = base64.urlsafe_b64encode(answer.key.encode()).decode()
        message = f"Invalid credentials: 'Authorization: Basic {basic}', token {bare}"
        answer.handler.send_json(401, {"error": {"message": message}} if answer.protocol == "openai"
                                 else {"error": message})

    def _key_in_json_500(self, answer: _Answer) -> None:
        message = f"upstream quota exceeded for key {answer.key}"
        answer.handler.send_json(500, {"error": {"message": message, "key": answer.key}} if answer.protocol == "openai"
                                 else {"error": message})

    def _key_mid_stream(self, answer: _Answer) -> None:
        answer.handler.start_stream(answer.content_type)
        answer.handler.write_chunk(self._stream_events(answer.protocol)[0])
        message = f"backend rejected token {answer.key} mid-way"
        if answer.protocol == "openai":
            answer.handler.write_chunk(b"data: " + json.dumps({"error": {"message": message}}).encode() + b"\n\n")
        else:
            answer.handler.write_chunk(json.dumps({"error": message}).encode() + b"\n")
        answer.handler.end_stream()

    def _malformed_json(self, answer: _Answer) -> None:
        if answer.stream:
            answer.handler.start_stream(answer.content_type)
            answer.handler.write_chunk(b"data: {not json\n\n" if answer.protocol == "openai" else b"{not json\n")
            answer.handler.end_stream()
        else:
            answer.handler.send_bytes(200, b'{"choices": [{"message": ', answer.content_type)

    def _reset_midway(self, answer: _Answer) -> None:
        self._first_part(answer)
        _reset(answer.handler)


@dataclass(frozen=True)
class _Answer:
    """What a mode needs to answer one chat request."""

    handler: ProtocolHandler
    protocol: str  # "openai" or "ollama"
    stream: bool
    content_type: str
    authorization: str  # the Authorization header as received
    key: str  # the bearer token (or X-Chroma-Token) as received


def _reset(handler: ProtocolHandler) -> None:
    """Close the connection with a TCP reset (SO_LINGER 0), as a crashed server or a proxy does."""
    handler.close_connection = True
    with contextlib.suppress(OSError):
        handler.connection.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        handler.connection.close()


def main() -> None:
    """Serve on a free port until interrupted, in the mode given as the first argument (default ok)."""
    import sys  # noqa: PLC0415  (only for running by hand)

    with FaultServer(mode=sys.argv[1] if len(sys.argv) > 1 else "ok") as server:
        print(f"fault server ({server.mode}) on http://127.0.0.1:{server.port}", flush=True)
        deadline = time.monotonic() + 3600
        while time.monotonic() < deadline:
            time.sleep(1.0)


if __name__ == "__main__":
    main()
