"""A stdlib Ollama server double that speaks Ollama's REST API with its real field names.

``OllamaTestServer`` listens on 127.0.0.1 (a free port) in a background thread. It keeps a set of
installed models and a "registry" of pullable ones, answers ``/api/version``, ``/api/tags``,
``/api/ps``, ``/api/show``, ``/api/pull``, ``/api/generate``, ``/api/chat`` and ``/api/embed``,
streams NDJSON with HTTP/1.1 chunked encoding as Ollama does, and records every request so tests
can assert what a client sent. Faults (a :class:`Fault` per path) make it cut a stream, never
answer, answer an error status, or report an error mid-stream.

The generic parts (:class:`ProtocolServer`, :class:`ProtocolHandler`, :class:`Fault`) are reused
by other protocol doubles.

Usage::

    with OllamaTestServer(models=["llama3.2:1b"]) as server:
        client = OllamaClient(OllamaModel(name="m", checkpoint="llama3.2:1b"), port=server.port)
        ...
        assert server.requests_to("/api/chat")[0].json["messages"][0]["role"] == "user"
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import re
import socket
import sys
import threading
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

__all__ = ["Fault", "OllamaTestServer", "ProtocolHandler", "ProtocolServer", "RecordedRequest"]


@dataclass(frozen=True)
class RecordedRequest:
    """One request as the server received it."""

    method: str
    path: str
    headers: dict[str, str]
    body: bytes
    json: Any = None


@dataclass
class Fault:
    """A misbehaviour for requests to ``path``.

    :param kind: ``"die"`` (close the socket after ``after`` streamed chunks), ``"hang"`` (never
        answer; the handler gives up after ``seconds`` or when the server stops), ``"status"``
        (answer ``status`` with the protocol's error body holding ``message``), ``"stream_error"``
        (stream ``after`` chunks, then the protocol's mid-stream error object).
    :param times: how many requests it applies to (None: all).
    """

    path: str
    kind: str
    after: int = 0
    seconds: float = 5.0
    status: int = 500
    message: str = "internal error"
    times: int | None = None


class _HTTPServer(ThreadingHTTPServer):
    daemon_threads = True

    def __init__(self, app: ProtocolServer) -> None:
        self.app = app
        super().__init__(("127.0.0.1", 0), app.handler_class)

    def handle_error(self, request: Any, client_address: Any) -> None:
        # A client that gives up (timeout, closed stream) is expected; anything else is a bug in
        # the double, kept for tests to check instead of printed to stderr.
        exc = sys.exc_info()[1]
        if not isinstance(exc, ConnectionError | TimeoutError):
            self.app.errors.append(exc)


class ProtocolHandler(BaseHTTPRequestHandler):
    """Request plumbing: body reading, JSON replies, chunked streams, faults; the app routes."""

    # HTTP/1.1 so streams use chunked encoding as the real servers do: a cut stream is then
    # distinguishable from a finished one.
    protocol_version = "HTTP/1.1"
    # Idle keep-alive connections end on their own even if a client never closes them.
    timeout = 10
    server: _HTTPServer

    def log_message(self, format: str, *args: Any) -> None:
        """Quiet: tests read ``requests`` instead of access logs."""

    def setup(self) -> None:
        super().setup()
        self.server.app.track(self.connection, open_=True)

    def finish(self) -> None:
        try:
            super().finish()
        finally:
            self.server.app.track(self.connection, open_=False)

    def do_GET(self) -> None:
        self._dispatch("GET")

    def do_POST(self) -> None:
        self._dispatch("POST")

    def do_DELETE(self) -> None:
        self._dispatch("DELETE")

    def do_HEAD(self) -> None:
        self._dispatch("HEAD")

    def _dispatch(self, method: str) -> None:
        app = self.server.app
        length = int(self.headers.get("Content-Length") or 0)
        raw = self.rfile.read(length) if length else b""
        parsed: Any = None
        if raw and "json" in (self.headers.get("Content-Type") or "json"):
            try:
                parsed = json.loads(raw)
            except ValueError:
                parsed = None
        path = self.path.split("?", 1)[0]
        request = RecordedRequest(method, path, {k.lower(): v for k, v in self.headers.items()}, raw, parsed)
        app.record(request)
        fault = app.take_fault(path)
        if fault is not None and fault.kind == "hang":
            app.wait_or_stop(fault.seconds)
            self.close_connection = True
            return
        if fault is not None and fault.kind == "status":
            self.send_json(fault.status, app.error_body(fault.message))
            return
        app.route(self, request, fault)

    # -- replies --------------------------------------------------------------------------------------

    def send_json(self, status: int, body: Any, content_type: str = "application/json; charset=utf-8") -> None:
        """A complete JSON reply with Content-Length."""
        self.send_bytes(status, json.dumps(body).encode(), content_type)

    def send_bytes(self, status: int, data: bytes, content_type: str) -> None:
        """A complete reply with Content-Length."""
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(data)

    def start_stream(self, content_type: str, status: int = 200) -> None:
        """Headers of a chunked reply."""
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Transfer-Encoding", "chunked")
        self.end_headers()

    def write_chunk(self, data: bytes) -> None:
        """One HTTP chunk, sent now."""
        self.wfile.write(b"%x\r\n%s\r\n" % (len(data), data))
        self.wfile.flush()

    def end_stream(self) -> None:
        """The last (empty) chunk."""
        self.wfile.write(b"0\r\n\r\n")
        self.wfile.flush()

    def die(self) -> None:
        """Drop the connection without finishing the reply."""
        self.close_connection = True
        with contextlib.suppress(OSError):
            self.connection.shutdown(socket.SHUT_RDWR)


class ProtocolServer:
    """A threaded HTTP server on 127.0.0.1:<free port> with request recording and faults.

    Subclasses set ``handler_class`` (usually :class:`ProtocolHandler`) and implement
    :meth:`route` and :meth:`error_body`.
    """

    handler_class: type[ProtocolHandler] = ProtocolHandler

    def __init__(self) -> None:
        self.requests: list[RecordedRequest] = []
        self.errors: list[BaseException | None] = []
        self.faults: list[Fault] = []
        self._lock = threading.Lock()
        self._stopping = threading.Event()
        self._connections: set[socket.socket] = set()
        self._server: _HTTPServer | None = None
        self._thread: threading.Thread | None = None

    # -- lifecycle ----------------------------------------------------------------------------------

    def start(self) -> ProtocolServer:
        """Bind a free port and serve in a background thread."""
        self._server = _HTTPServer(self)
        self._thread = threading.Thread(target=self._server.serve_forever, kwargs={"poll_interval": 0.05},
                                        name=f"{type(self).__name__}", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop serving, drop open connections and wait (bounded) for the handler threads."""
        if self._server is None:
            return
        self._stopping.set()
        self._server.shutdown()
        with self._lock:
            connections = list(self._connections)
        for connection in connections:
            with contextlib.suppress(OSError):
                connection.shutdown(socket.SHUT_RDWR)
        # Joins the handler threads: each ends promptly now that its socket is shut down and
        # hanging handlers watch _stopping.
        self._server.server_close()
        if self._thread is not None:
            self._thread.join(5.0)
        self._server = None

    def __enter__(self) -> ProtocolServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def port(self) -> int:
        """The port it listens on."""
        assert self._server is not None, "start() the server first"
        return int(self._server.server_address[1])

    # -- bookkeeping ----------------------------------------------------------------------------------

    def track(self, connection: socket.socket, open_: bool) -> None:
        with self._lock:
            if open_:
                self._connections.add(connection)
            else:
                self._connections.discard(connection)

    def record(self, request: RecordedRequest) -> None:
        with self._lock:
            self.requests.append(request)

    def requests_to(self, path: str) -> list[RecordedRequest]:
        """The requests received for ``path``, oldest first."""
        with self._lock:
            return [r for r in self.requests if r.path == path]

    def add_fault(self, fault: Fault) -> None:
        with self._lock:
            self.faults.append(fault)

    def take_fault(self, path: str) -> Fault | None:
        with self._lock:
            for fault in self.faults:
                if fault.path == path:
                    if fault.times is not None:
                        fault.times -= 1
                        if fault.times <= 0:
                            self.faults.remove(fault)
                    return fault
        return None

    def wait_or_stop(self, seconds: float) -> bool:
        """Sleep up to ``seconds``, returning early when the server stops; returns whether it stops."""
        return self._stopping.wait(seconds)

    # -- what subclasses implement ------------------------------------------------------------------

    def route(self, handler: ProtocolHandler, request: RecordedRequest, fault: Fault | None) -> None:
        raise NotImplementedError

    def error_body(self, message: str) -> Any:
        raise NotImplementedError


def _now() -> str:
    # Ollama writes RFC 3339 timestamps with nanoseconds; microseconds read the same to clients.
    return datetime.now(timezone.utc).isoformat().replace("+00:00", "Z")


def canonical(name: str) -> str:
    """Ollama's model-name rule: no tag means ``:latest``."""
    return name if ":" in name.rsplit("/", 1)[-1] else f"{name}:latest"


def _digest(name: str) -> str:
    return hashlib.sha256(name.encode()).hexdigest()


def _pieces(text: str) -> list[str]:
    """Split an answer into streamed pieces (a word and its trailing space each)."""
    return re.findall(r"\S+\s*", text) or [text]


def fake_embedding(text: str, dim: int = 8) -> list[float]:
    """A deterministic vector for ``text`` (tests compare it with what the client returns)."""
    digest = hashlib.sha256(text.encode()).digest()
    return [round(b / 255.0, 6) for b in digest[:dim]]


class OllamaTestServer(ProtocolServer):
    """Ollama's REST API over installed models and a pullable registry.

    :param models: names installed from the start.
    :param registry: names ``/api/pull`` can fetch (others fail as Ollama does).
    :param reply: the chat / generate answer; None answers ``"You said: <last user message>"``.
    :param tool_calls: ``[{"name", "arguments"}]`` the model calls when a request carries tools.
    :param pull_steps: progress messages per layer during a pull.
    :param version: what ``/api/version`` says.
    """

    def __init__(self, models: list[str] | None = None, registry: list[str] | None = None, reply: str | None = None,
                 tool_calls: list[dict[str, Any]] | None = None, pull_steps: int = 5, version: str = "0.9.6") -> None:
        super().__init__()
        self.installed: set[str] = {canonical(m) for m in (models or [])}
        self.registry: set[str] = {canonical(m) for m in (registry or [])}
        self.loaded: set[str] = set()
        self.reply = reply
        self.tool_calls = tool_calls
        self.pull_steps = pull_steps
        self.version = version

    def error_body(self, message: str) -> Any:
        return {"error": message}

    # -- routing --------------------------------------------------------------------------------------

    def route(self, handler: ProtocolHandler, request: RecordedRequest, fault: Fault | None) -> None:
        routes = {
            ("GET", "/api/version"): self._version,
            ("GET", "/api/tags"): self._tags,
            ("GET", "/api/ps"): self._ps,
            ("POST", "/api/show"): self._show,
            ("POST", "/api/pull"): self._pull,
            ("POST", "/api/generate"): self._generate,
            ("POST", "/api/chat"): self._chat,
            ("POST", "/api/embed"): self._embed,
        }
        action = routes.get((request.method, request.path))
        if action is None:
            # Ollama's router answers unknown paths with a plain-text 404.
            handler.send_bytes(404, b"404 page not found", "text/plain")
            return
        if request.method == "POST" and not isinstance(request.json, dict):
            handler.send_json(400, {"error": "invalid request body"})
            return
        action(handler, request.json or {}, fault)

    def _model_of(self, handler: ProtocolHandler, body: dict[str, Any]) -> str | None:
        """The canonical model name of a request, or None after answering its error."""
        name = body.get("model") or body.get("name")
        if not isinstance(name, str) or not name:
            handler.send_json(400, {"error": "model is required"})
            return None
        name = canonical(name)
        if name not in self.installed:
            shown = name.removesuffix(":latest")
            handler.send_json(404, {"error": f"model \"{shown}\" not found, try pulling it first"})
            return None
        return name

    def _version(self, handler: ProtocolHandler, body: dict[str, Any], fault: Fault | None) -> None:
        handler.send_json(200, {"version": self.version})

    def _model_entry(self, name: str) -> dict[str, Any]:
        return {"name": name, "model": name, "modified_at": _now(), "size": 1_234_567, "digest": _digest(name),
                "details": {"parent_model": "", "format": "gguf", "family": "llama", "families": ["llama"],
                            "parameter_size": "1.2B", "quantization_level": "Q4_K_M"}}

    def _tags(self, handler: ProtocolHandler, body: dict[str, Any], fault: Fault | None) -> None:
        handler.send_json(200, {"models": [self._model_entry(name) for name in sorted(self.installed)]})

    def _ps(self, handler: ProtocolHandler, body: dict[str, Any], fault: Fault | None) -> None:
        handler.send_json(200, {"models": [{**self._model_entry(name), "expires_at": _now(), "size_vram": 0}
                                           for name in sorted(self.loaded)]})

    def _show(self, handler: ProtocolHandler, body: dict[str, Any], fault: Fault | None) -> None:
        name = body.get("model") or body.get("name")
        if not isinstance(name, str) or canonical(name) not in self.installed:
            handler.send_json(404, {"error": f"model '{name}' not found"})
            return
        entry = self._model_entry(canonical(name))
        handler.send_json(200, {
            "modelfile": f"# Modelfile generated by \"ollama show\"\nFROM {name}\n",
            "parameters": "stop                           \"<|eot_id|>\"",
            "template": "{{ .Prompt }}",
            "details": entry["details"],
            "model_info": {"general.architecture": "llama", "llama.context_length": 8192},
            "capabilities": ["completion", "tools"],
            "modified_at": entry["modified_at"],
        })

    def _pull(self, handler: ProtocolHandler, body: dict[str, Any], fault: Fault | None) -> None:
        name = body.get("model") or body.get("name")
        if not isinstance(name, str) or not name:
            handler.send_json(400, {"error": "model is required"})
            return
        name = canonical(name)
        lines: list[dict[str, Any]] = [{"status": "pulling manifest"}]
        if name not in self.registry and name not in self.installed:
            # Ollama has already sent 200 and streams the failure as an error line.
            lines.append({"error": "pull model manifest: file does not exist"})
        else:
            for layer, total in ((_digest(name)[:12], 1_000_000), (_digest(name + "/params")[:12], 4_000)):
                digest = f"sha256:{_digest(layer)}"
                for step in range(self.pull_steps + 1):
                    lines.append({"status": f"pulling {layer}", "digest": digest, "total": total,
                                  "completed": total * step // self.pull_steps})
            lines += [{"status": "verifying sha256 digest"}, {"status": "writing manifest"},
                      {"status": "removing any unused layers"}, {"status": "success"}]
        if body.get("stream") is False:
            last = lines[-1]
            if "error" in last:
                handler.send_json(500, last)
            else:
                self.installed.add(name)
                handler.send_json(200, last)
            return
        handler.start_stream("application/x-ndjson")
        for line in lines:
            handler.write_chunk(json.dumps(line).encode() + b"\n")
        if lines[-1].get("status") == "success":
            self.installed.add(name)
        handler.end_stream()

    # -- inference ------------------------------------------------------------------------------------

    def _answer_text(self, messages: list[Any]) -> str:
        if self.reply is not None:
            return self.reply
        users = [m.get("content", "") for m in messages if isinstance(m, dict) and m.get("role") == "user"]
        return f"You said: {users[-1] if users else ''}"

    def _stats(self, eval_count: int) -> dict[str, Any]:
        return {"total_duration": 5_000_000 + eval_count * 1_000_000, "load_duration": 1_000_000,
                "prompt_eval_count": 12, "prompt_eval_duration": 2_000_000, "eval_count": eval_count,
                "eval_duration": eval_count * 1_000_000}

    def _stream_lines(self, handler: ProtocolHandler, lines: list[dict[str, Any]], fault: Fault | None) -> None:
        handler.start_stream("application/x-ndjson")
        for index, line in enumerate(lines):
            if fault is not None and index == fault.after:
                if fault.kind == "die":
                    handler.die()
                    return
                if fault.kind == "stream_error":
                    handler.write_chunk(json.dumps({"error": fault.message}).encode() + b"\n")
                    handler.end_stream()
                    return
            handler.write_chunk(json.dumps(line).encode() + b"\n")
        handler.end_stream()

    def _generate(self, handler: ProtocolHandler, body: dict[str, Any], fault: Fault | None) -> None:
        name = self._model_of(handler, body)
        if name is None:
            return
        prompt = body.get("prompt") or ""
        base = {"model": body.get("model"), "created_at": _now()}
        if not prompt and not body.get("images"):
            # Ollama's documented load / unload requests: empty prompt, keep_alive 0 unloads.
            if body.get("keep_alive") in (0, "0", "0s"):
                self.loaded.discard(name)
                reply = {**base, "response": "", "done": True, "done_reason": "unload"}
            else:
                self.loaded.add(name)
                reply = {**base, "response": "", "done": True, "done_reason": "load"}
            handler.send_json(200, reply)
            return
        self.loaded.add(name)
        text = self.reply if self.reply is not None else f"You said: {prompt}"
        pieces = _pieces(text)
        if body.get("stream") is False:
            handler.send_json(200, {**base, "response": text, "done": True, "done_reason": "stop",
                                    "context": [1, 2, 3], **self._stats(len(pieces))})
            return
        lines = [{**base, "response": piece, "done": False} for piece in pieces]
        lines.append({**base, "response": "", "done": True, "done_reason": "stop", "context": [1, 2, 3],
                      **self._stats(len(pieces))})
        self._stream_lines(handler, lines, fault)

    def _chat(self, handler: ProtocolHandler, body: dict[str, Any], fault: Fault | None) -> None:
        name = self._model_of(handler, body)
        if name is None:
            return
        messages = body.get("messages")
        if not isinstance(messages, list):
            handler.send_json(400, {"error": "messages is required"})
            return
        self.loaded.add(name)
        base = {"model": body.get("model"), "created_at": _now()}
        calls: list[dict[str, Any]] = []
        if body.get("tools") and self.tool_calls:
            calls = [{"function": {"index": i, "name": c["name"], "arguments": c.get("arguments", {})}}
                     for i, c in enumerate(self.tool_calls)]
        text = "" if calls else self._answer_text(messages)
        pieces = _pieces(text) if text else []
        if body.get("stream") is False:
            message: dict[str, Any] = {"role": "assistant", "content": text}
            if calls:
                message["tool_calls"] = calls
            handler.send_json(200, {**base, "message": message, "done_reason": "stop", "done": True,
                                    **self._stats(max(1, len(pieces)))})
            return
        lines: list[dict[str, Any]] = [{**base, "message": {"role": "assistant", "content": piece}, "done": False}
                                       for piece in pieces]
        if calls:
            lines.append({**base, "message": {"role": "assistant", "content": "", "tool_calls": calls}, "done": False})
        lines.append({**base, "message": {"role": "assistant", "content": ""}, "done_reason": "stop", "done": True,
                      **self._stats(max(1, len(pieces)))})
        self._stream_lines(handler, lines, fault)

    def _embed(self, handler: ProtocolHandler, body: dict[str, Any], fault: Fault | None) -> None:
        name = self._model_of(handler, body)
        if name is None:
            return
        inputs = body.get("input")
        texts = [inputs] if isinstance(inputs, str) else inputs
        if not isinstance(texts, list) or not all(isinstance(t, str) for t in texts):
            handler.send_json(400, {"error": "invalid input type"})
            return
        self.loaded.add(name)
        handler.send_json(200, {"model": body.get("model"), "embeddings": [fake_embedding(t) for t in texts],
                                "total_duration": 14_143_917, "load_duration": 1_019_500,
                                "prompt_eval_count": sum(len(t.split()) for t in texts)})


def main() -> None:
    """Serve on a free port until interrupted (for poking at it by hand)."""
    with OllamaTestServer(models=["llama3.2:1b"], registry=["qwen3:0.6b"]) as server:
        print(f"Ollama test server on http://127.0.0.1:{server.port}", flush=True)
        deadline = time.monotonic() + 3600
        while time.monotonic() < deadline:
            time.sleep(1.0)


if __name__ == "__main__":
    main()
