"""A RoboML server double speaking RoboML 0.6.1's HTTP, WebSocket and RESP protocols.

``RoboMLTestServer`` serves, on 127.0.0.1 and free ports:

* one port for HTTP and WebSocket, as RoboML's Ray Serve app does: ``GET /``, ``GET /v1/models``,
  ``POST /add_node`` (201), ``POST /remove_node`` (202), ``POST /<node>/initialize``,
  ``POST /<node>/inference`` (JSON, or a chunked ``text/plain`` token stream), ``GET
  /<node>/get_status`` and the WebSocket ``/<node>/ws_inference`` (msgpack request frames; token
  text frames ended by ``"<<Response Ended>>"``; close code 1007 with the error as reason). The
  port is a ``websockets.sync.server.serve`` server whose connection factory answers the
  requests that are not a WebSocket upgrade as HTTP (websockets' own parser takes GET only).
* ``resp_port``: RoboML's RESP2 server: ``PING``, ``CLIENT ..``, ``QUIT``, ``add_node``,
  ``remove_node``, ``<node>.initialize|inference|get_status`` with one msgpack map argument, the
  same reply and error lines (and the same quirk: an empty argument map gets no reply).

Status codes, bodies, error texts and init-parameter checks follow RoboML's source. Fake models
answer deterministically: chat echoes the last message (streamed word by word), speech-to-text
counts samples, text-to-speech returns a small WAV, detection returns one box per image. Arrays
are decoded with msgpack-numpy's format and PNGs with a small decoder written here, independent
of the client's helpers. Every request is recorded in ``calls``.

Faults (:meth:`RoboMLTestServer.set_fault`) act on inference requests: ``"hang"`` (answer only
after ``seconds``, or never if the server stops first), ``"die"`` (drop the connection, after
``after`` streamed chunks), ``"error"`` (the model raises ``message``), ``"drop_after_reply"``
(answer, then drop the connection), ``"bad_frame"`` (answer with bytes that are not msgpack).
"""

from __future__ import annotations

import base64
import contextlib
import json
import socket
import struct
import threading
import time
import zlib
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler
from typing import Any
from urllib.parse import parse_qs, urlsplit

import msgpack
import numpy as np
from websockets.exceptions import ConnectionClosed
from websockets.sync.server import Server, ServerConnection, serve

__all__ = ["Call", "RoboMLTestServer", "decode_png"]

#: RoboML 0.6.1's model classes and the keyword arguments of their ``_initialize``.
INIT_PARAMS: dict[str, set[str]] = {
    "TransformersLLM": {"checkpoint", "quantization", "system_prompt", "source"},
    "TransformersMLLM": {"checkpoint", "quantization", "system_prompt", "source"},
    "RoboBrain2": {"checkpoint", "source"},
    "Whisper": {"checkpoint", "compute_type", "source"},
    "TransformersTTS": {"checkpoint", "voice", "vocoder_checkpoint", "source"},
    "VisionModel": {"checkpoint", "setup_trackers", "num_trackers", "tracking_distance_threshold", "source"},
}
STREAMING = {"TransformersLLM", "TransformersMLLM"}
RESPONSE_ENDED = "<<Response Ended>>"
CHUNK_SIZE = 1024 * 1024


@dataclass(frozen=True)
class Call:
    """One request as the server understood it."""

    transport: str  # "http", "ws" or "resp"
    op: str  # "add_node", "remove_node", "initialize", "inference", "get_status", "ping", ...
    node: str | None
    payload: Any  # decoded body / arguments (arrays as ndarrays, PNGs still base64)


@dataclass
class _Fault:
    kind: str
    op: str
    times: int
    after: int
    seconds: float
    message: str


class ValidationError(Exception):
    """The input did not fit the node's input model (pydantic's errors in ``errors``)."""

    def __init__(self, errors: list[dict[str, Any]]) -> None:
        super().__init__(f"{len(errors)} validation error(s)")
        self.errors = errors


class _NotWebSocket(Exception):
    """Raised by the connection factory after serving a plain HTTP request."""


# -- formats written independently of the client -----------------------------------------------


def _np_decode(obj: dict[Any, Any]) -> Any:
    if obj.get(b"nd") is True:
        return np.frombuffer(obj[b"data"], dtype=np.dtype(obj[b"type"])).reshape(obj[b"shape"])
    if obj.get(b"nd") is False:
        return np.frombuffer(obj[b"data"], dtype=np.dtype(obj[b"type"]))[0]
    return obj


def _np_encode(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return {b"nd": True, b"type": obj.dtype.str, b"kind": b"", b"shape": obj.shape, b"data": obj.tobytes()}
    raise TypeError(f"can not serialize {type(obj).__name__!r} object")


def mp_unpack(data: bytes) -> Any:
    """msgpack as RoboML's patched ``msgpack.unpackb`` reads it."""
    return msgpack.unpackb(data, object_hook=_np_decode)


def mp_pack(obj: Any) -> bytes:
    """msgpack as RoboML's patched ``msgpack.packb`` writes it."""
    return msgpack.packb(obj, default=_np_encode)


def decode_png(data: bytes) -> np.ndarray:
    """Decode an 8-bit, non-interlaced PNG (gray, RGB or RGBA) into an array."""
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("not a PNG")
    pos, idat, header = 8, b"", b""
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            header = body
        elif kind == b"IDAT":
            idat += body
    width, height, depth, color, _, _, interlace = struct.unpack(">IIBBBBB", header)
    channels = {0: 1, 2: 3, 6: 4}[color]
    if depth != 8 or interlace:
        raise ValueError("only 8-bit non-interlaced PNGs")
    stride = width * channels
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(height, stride + 1)
    rows = np.zeros((height, stride), np.int32)
    for y in range(height):
        line, prev = raw[y, 1:].astype(np.int32), rows[y - 1] if y else np.zeros(stride, np.int32)
        kind = raw[y, 0]
        if kind == 0:
            rows[y] = line
        elif kind == 2:
            rows[y] = (line + prev) % 256
        else:
            raise ValueError(f"PNG filter {kind} not supported by the double")
    image = rows.astype(np.uint8)
    return image.reshape(height, width) if channels == 1 else image.reshape(height, width, channels)


def _wav(samples: int) -> bytes:
    data = np.zeros(samples, "<i2").tobytes()
    return (b"RIFF" + struct.pack("<I", 36 + len(data)) + b"WAVEfmt " + struct.pack("<IHHIIHH", 16, 1, 1, 16000,
            32000, 2, 16) + b"data" + struct.pack("<I", len(data)) + data)


def _image(img: Any) -> np.ndarray:
    return img if isinstance(img, np.ndarray) else decode_png(base64.b64decode(img))


# -- fake RoboML nodes ---------------------------------------------------------------------------


class _Node:
    def __init__(self, name: str, model: str) -> None:
        self.name, self.model, self.status = name, model, "LOADED"
        self.init_params: dict[str, Any] = {}

    def initialize(self, params: dict[str, Any]) -> None:
        if self.status == "READY":
            return
        unexpected = sorted(set(params) - INIT_PARAMS[self.model])
        if unexpected:
            self.status = "INITIALIZATION_ERROR"
            raise ValidationError([{"type": "unexpected_keyword_argument", "loc": [k],
                                    "msg": "Unexpected keyword argument"} for k in unexpected])
        self.init_params = dict(params)
        self.status = "READY"

    def validate(self, data: Any) -> dict[str, Any]:
        """A light version of the pydantic input models in roboml/interfaces.py."""
        if not isinstance(data, dict):
            raise ValidationError([{"type": "model_type", "loc": [], "msg": "Input should be a valid dictionary"}])
        errors: list[dict[str, Any]] = []

        def need(key: str, ok: bool, msg: str) -> None:
            if not ok:
                errors.append({"type": "value_error", "loc": [key], "msg": msg})

        if self.model in ("TransformersLLM", "TransformersMLLM", "RoboBrain2"):
            query = data.get("query")
            need("query", isinstance(query, list) and bool(query) and all(isinstance(m, dict) for m in query),
                 "Input should be a non-empty list of dicts")
            need("temperature", data.get("temperature", 0.7) > 0, "Input should be greater than 0")
            if self.model != "TransformersLLM":
                need("images", bool(data.get("images")), "At least one image or video must be provided.")
        elif self.model == "Whisper":
            query = data.get("query")
            need("query", isinstance(query, str | bytes | np.ndarray) and len(query) > 0, "Field required")
        elif self.model == "TransformersTTS":
            need("query", isinstance(data.get("query"), str), "Input should be a valid string")
        else:
            need("images", isinstance(data.get("images"), list) and bool(data["images"]),
                 "List should have at least 1 item after validation")
        if errors:
            raise ValidationError(errors)
        return data

    def infer(self, data: dict[str, Any]) -> tuple[dict[str, Any] | None, list[str] | None]:
        """(result, None) or (None, tokens) when the model streams."""
        if self.status != "READY":
            raise RuntimeError("Inference called before initialization")
        data = self.validate(data)
        if self.model in ("TransformersLLM", "TransformersMLLM"):
            text = f"echo: {data['query'][-1].get('content', '')}"
            if self.model == "TransformersMLLM":
                text += " | images: " + ", ".join("x".join(map(str, _image(i).shape)) for i in data["images"])
            if data.get("stream"):
                return None, [w + " " for w in text.split(" ")[:-1]] + [text.split(" ")[-1]]
            return {"output": text}, None
        if self.model == "RoboBrain2":
            return {"output": [[12, 34]], "thinking": ""}, None
        if self.model == "Whisper":
            query = data["query"]
            audio = base64.b64decode(query) if isinstance(query, str) else query
            samples = len(audio) // 2 if isinstance(audio, bytes) else int(audio.size)
            if data.get("word_timestamps"):
                return {"output": [[0.0, 0.5, "heard"], [0.5, 1.0, str(samples)]]}, None
            return {"output": f"heard {samples} samples"}, None
        if self.model == "TransformersTTS":
            wav = _wav(10 * len(data["query"]))
            return {"output": wav if data.get("get_bytes") else base64.b64encode(wav).decode()}, None
        results = []
        for img in data["images"]:
            height, width = _image(img).shape[:2]
            result: dict[str, Any] = {"bboxes": [[0.0, 0.0, float(width), float(height)]], "labels": ["object"],
                                      "scores": [0.9]}
            if data.get("labels_to_track") and self.init_params.get("setup_trackers"):
                result |= {"tracked_bboxes": result["bboxes"], "tracked_points": [[width / 2, height / 2]],
                           "tracked_labels": ["object"], "ids": [1]}
            results.append(result)
        return {"output": results}, None


# -- the server --------------------------------------------------------------------------------


class _HTTPHandler(BaseHTTPRequestHandler):
    # HTTP/1.1 with chunked streams, as uvicorn answers: a cut stream is then detectable.
    protocol_version = "HTTP/1.1"
    server: RoboMLTestServer  # type: ignore[assignment]

    def log_message(self, format: str, *args: Any) -> None:
        """Quiet: tests read ``calls``."""

    def do_GET(self) -> None:
        self.server.handle_http(self, "GET")

    def do_POST(self) -> None:
        self.server.handle_http(self, "POST")

    def reply(self, status: int, body: Any) -> None:
        data = json.dumps(body).encode()
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        self.send_header("Connection", "close")
        self.end_headers()
        self.wfile.write(data)

    def drop(self) -> None:
        self.close_connection = True
        with contextlib.suppress(OSError):
            self.connection.shutdown(socket.SHUT_RDWR)


class RoboMLTestServer:
    """The RoboML double; use as a context manager or call :meth:`start` / :meth:`stop`."""

    def __init__(self) -> None:
        self.calls: list[Call] = []
        self.nodes: dict[str, _Node] = {}
        self.ws_connections = 0
        self.errors: list[BaseException] = []
        self._fault: _Fault | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._ws_server: Server | None = None
        self._threads: list[threading.Thread] = []
        self._resp_listener: socket.socket | None = None
        self._resp_sockets: set[socket.socket] = set()
        self._resp_threads: list[threading.Thread] = []
        self.port = 0
        self.resp_port = 0

    # -- lifecycle ----------------------------------------------------------------------------

    def start(self) -> RoboMLTestServer:
        """Listen on free ports and serve in background threads."""
        self._ws_server = serve(self._ws_handler, "127.0.0.1", 0, create_connection=self._connection_factory,
                                process_request=self._ws_route, compression=None, ping_interval=None,
                                max_size=None, close_timeout=1)
        self.port = self._ws_server.socket.getsockname()[1]
        self._resp_listener = socket.create_server(("127.0.0.1", 0))
        self._resp_listener.settimeout(0.05)
        self.resp_port = self._resp_listener.getsockname()[1]
        for target in (self._ws_server.serve_forever, self._resp_accept):
            thread = threading.Thread(target=target, daemon=True, name=f"roboml-double-{target.__name__}")
            thread.start()
            self._threads.append(thread)
        return self

    def stop(self) -> None:
        """Stop serving: close every socket and join every thread (bounded)."""
        self._stop.set()
        if self._ws_server is not None:
            self._ws_server.shutdown()  # closes WebSocket connections, joins handler threads
        with self._lock:
            sockets = list(self._resp_sockets)
        for sock in sockets:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)
        for thread in self._threads:  # the accept loops first: then no new handler thread appears
            thread.join(5.0)
        for thread in self._resp_threads:
            thread.join(5.0)
        if self._resp_listener is not None:
            self._resp_listener.close()
        self._ws_server = None

    def __enter__(self) -> RoboMLTestServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- test controls ------------------------------------------------------------------------

    def set_fault(self, kind: str | None, *, op: str = "inference", times: int = 1, after: int = 2,
                  seconds: float = 3.0, message: str = "model exploded") -> None:
        """Misbehave on the next ``times`` requests of ``op`` (None clears).

        ``op`` is ``"inference"`` (every kind) or ``"initialize"`` (``"hang"`` only).
        """
        with self._lock:
            self._fault = None if kind is None else _Fault(kind, op, times, after, seconds, message)

    def _take_fault(self, op: str = "inference") -> _Fault | None:
        with self._lock:
            fault = self._fault
            if fault is None or fault.op != op:
                return None
            fault.times -= 1
            if fault.times <= 0:
                self._fault = None
            return fault

    def calls_of(self, op: str, transport: str | None = None) -> list[Call]:
        """Recorded calls of one operation, oldest first."""
        with self._lock:
            return [c for c in self.calls if c.op == op and transport in (None, c.transport)]

    def _record(self, transport: str, op: str, node: str | None, payload: Any) -> None:
        with self._lock:
            self.calls.append(Call(transport, op, node, payload))

    def _hang(self, fault: _Fault) -> bool:
        """Wait out a hang; True when the server is stopping (then nothing is sent)."""
        return self._stop.wait(fault.seconds)

    # -- node operations shared by the transports --------------------------------------------

    def _add_node(self, name: str, model: str) -> dict[str, Any]:
        if name in self.nodes:
            return {"node": name, "warning": f"Name duplication. A model/db with name {name} already exists."}
        if model not in INIT_PARAMS:
            raise LookupError(f"{model} is not a supported model type in roboml library. Please use an available "
                              "model type or use another client.")
        self.nodes[name] = _Node(name, model)
        return {"node": name}

    # -- HTTP -----------------------------------------------------------------------------------

    def _connection_factory(self, sock: socket.socket, protocol: Any, server: Server, **kwargs: Any) -> Any:
        # Peek at the request line: a WebSocket upgrade goes to websockets, anything else is
        # answered here as HTTP and the connection then ends.
        deadline, line = time.monotonic() + 2.0, b""
        sock.settimeout(0.05)
        while time.monotonic() < deadline and b"\r\n" not in line and not self._stop.is_set():
            try:
                line = sock.recv(2048, socket.MSG_PEEK)
            except TimeoutError:
                continue
            if not line:
                break
            time.sleep(0.001)
        parts = line.split(b"\r\n", 1)[0].split(b" ")
        if len(parts) >= 2 and parts[0] == b"GET" and parts[1].endswith(b"/ws_inference"):
            sock.settimeout(None)
            return ServerConnection(sock, protocol, server, **kwargs)
        sock.settimeout(5.0)
        try:
            _HTTPHandler(sock, sock.getpeername(), self)
        except OSError:
            pass  # the client went away (a timeout on its side, a test's fault)
        except Exception as exc:  # a bug in the double: keep it for the test to see
            self.errors.append(exc)
        raise _NotWebSocket

    def handle_http(self, h: _HTTPHandler, method: str) -> None:
        url = urlsplit(h.path)
        query = {k: v[0] for k, v in parse_qs(url.query).items()}
        length = int(h.headers.get("Content-Length") or 0)
        raw = h.rfile.read(length) if length else b""
        try:
            body = json.loads(raw) if raw else None
        except ValueError:
            h.reply(422, {"detail": [{"type": "json_invalid", "loc": ["body"], "msg": "JSON decode error"}]})
            return
        segments = [s for s in url.path.split("/") if s]
        if method == "GET" and not segments:
            self._record("http", "about", None, None)
            h.reply(200, {"title": "roboml HTTP Server", "apps_served": list(self.nodes), "available_resources": {}})
        elif method == "GET" and segments == ["v1", "models"]:
            h.reply(200, {"object": "list", "data": [{"id": n, "object": "model", "owned_by": "roboml"}
                                                     for n in self.nodes]})
        elif method == "POST" and segments in (["add_node"], ["remove_node"]):
            self._http_node_admin(h, segments[0], query)
        elif len(segments) == 2 and segments[0] in self.nodes:
            self._http_node_route(h, method, self.nodes[segments[0]], segments[1], body)
        else:
            h.reply(404, {"detail": "Not Found"})

    def _http_node_admin(self, h: _HTTPHandler, op: str, query: dict[str, str]) -> None:
        needed = ["node_name", "node_model"] if op == "add_node" else ["node_name"]
        self._record("http", op, query.get("node_name"), dict(query))
        missing = [k for k in needed if k not in query]
        if missing:
            h.reply(422, {"detail": [{"type": "missing", "loc": ["query", k], "msg": "Field required"}
                                     for k in missing]})
            return
        name = query["node_name"]
        if op == "add_node":
            try:
                h.reply(201, self._add_node(name, query["node_model"]))
            except LookupError as exc:
                h.reply(400, {"detail": str(exc)})
        elif name not in self.nodes:
            h.reply(400, {"detail": f"Node with name {name} does not exists."})
        else:
            del self.nodes[name]
            h.reply(202, {"node": name})

    def _http_node_route(self, h: _HTTPHandler, method: str, node: _Node, op: str, body: Any) -> None:
        if method == "GET" and op == "get_status":
            self._record("http", op, node.name, None)
            h.reply(200, node.status)
            return
        if method != "POST" or op not in ("initialize", "inference"):
            h.reply(404, {"detail": "Not Found"})
            return
        self._record("http", op, node.name, body)
        if op == "initialize":
            init_fault = self._take_fault("initialize")
            if init_fault is not None and self._hang(init_fault):
                h.drop()
                return
            try:
                node.initialize(body or {})
                h.reply(200, None)
            except ValidationError as exc:
                h.reply(500, {"detail": f"Initialization Error: {exc.errors}"})
            return
        fault = self._take_fault()
        if fault is not None and fault.kind == "hang" and self._hang(fault):
            h.drop()
            return
        if fault is not None and fault.kind == "die" and not (isinstance(body, dict) and body.get("stream")):
            h.drop()
            return
        if node.status != "READY":
            h.reply(500, {"detail": "Inference called before initialization"})
            return
        try:
            if fault is not None and fault.kind == "error":
                raise RuntimeError(fault.message)
            result, tokens = node.infer(body)
        except ValidationError as exc:
            h.reply(400, {"detail": exc.errors})
            return
        except Exception as exc:
            h.reply(500, {"detail": str(exc)})
            return
        if tokens is None:
            h.reply(200, result)
            return
        h.send_response(200)
        h.send_header("Content-Type", "text/plain; charset=utf-8")
        h.send_header("Transfer-Encoding", "chunked")
        h.send_header("Connection", "close")
        h.end_headers()
        for i, token in enumerate(tokens):
            if fault is not None and fault.kind == "die" and i == fault.after:
                h.drop()
                return
            data = token.encode()
            h.wfile.write(b"%x\r\n%s\r\n" % (len(data), data))
            h.wfile.flush()
        h.wfile.write(b"0\r\n\r\n")

    # -- WebSocket ------------------------------------------------------------------------------

    def _ws_route(self, connection: ServerConnection, request: Any) -> Any:
        node = request.path.strip("/").split("/")[0]
        if node not in self.nodes:
            return connection.respond(404, "Not Found")
        return None

    def _ws_handler(self, ws: ServerConnection) -> None:
        node = self.nodes.get(ws.request.path.strip("/").split("/")[0]) if ws.request else None
        with self._lock:
            self.ws_connections += 1
        while node is not None and not self._stop.is_set():
            try:
                raw = ws.recv()
            except ConnectionClosed:
                return
            try:
                if not isinstance(raw, bytes):
                    raise TypeError("Expected bytes websocket messages, got text")
                data = mp_unpack(raw)
                self._record("ws", "inference", node.name, data)
                # As RoboML: the end-of-audio check compares the query itself with b"\r\n" (an
                # array query makes that comparison raise under numpy 2, closing with 1007).
                if isinstance(data, dict) and data.get("query") == b"\r\n":
                    ws.send(mp_pack(data["query"]))
                    continue
                if not self._ws_inference(ws, node, data):
                    return
            except ValidationError as exc:
                ws.close(1007, str(exc.errors)[:120])
                return
            except ConnectionClosed:
                return
            except Exception as exc:
                ws.close(1007, str(exc)[:120])
                return

    def _ws_drop(self, ws: ServerConnection) -> None:
        with contextlib.suppress(OSError):
            ws.socket.shutdown(socket.SHUT_RDWR)

    def _ws_inference(self, ws: ServerConnection, node: _Node, data: Any) -> bool:
        """Answer one request; False when the connection is gone."""
        fault = self._take_fault()
        kind = fault.kind if fault is not None else None
        if fault is not None and kind == "hang" and self._hang(fault):
            return False
        if kind == "error":
            raise RuntimeError(fault.message if fault else "")
        result, tokens = node.infer(data)
        if kind == "die" and tokens is None:
            self._ws_drop(ws)
            return False
        if tokens is not None:
            for i, token in enumerate(tokens):
                if fault is not None and kind == "die" and i == fault.after:
                    self._ws_drop(ws)
                    return False
                ws.send(token)
            if kind == "bad_frame":
                ws.send(b"\xc1 not msgpack")
            ws.send(RESPONSE_ENDED)
        else:
            assert result is not None
            output = result["output"]
            if kind == "bad_frame":
                ws.send(b"\xc1 not msgpack")
            elif isinstance(output, str):
                step = CHUNK_SIZE if len(output.encode()) > CHUNK_SIZE else max(len(output), 1)
                for i in range(0, max(len(output), 1), step):
                    ws.send(output[i:i + step])
            else:
                blob = output if isinstance(output, bytes) else mp_pack(output)
                for i in range(0, max(len(blob), 1), CHUNK_SIZE):
                    ws.send(blob[i:i + CHUNK_SIZE])
        if kind == "drop_after_reply":
            self._ws_drop(ws)
            return False
        return True

    # -- RESP -----------------------------------------------------------------------------------

    def _resp_accept(self) -> None:
        assert self._resp_listener is not None
        while not self._stop.is_set():
            try:
                sock, _ = self._resp_listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            sock.settimeout(0.1)
            with self._lock:
                self._resp_sockets.add(sock)
            thread = threading.Thread(target=self._resp_connection, args=(sock,), daemon=True)
            self._resp_threads.append(thread)
            thread.start()

    def _resp_connection(self, sock: socket.socket) -> None:
        buffer = bytearray()

        def read_line() -> bytes | None:
            while b"\r\n" not in buffer:
                if self._stop.is_set():
                    return None
                try:
                    data = sock.recv(65536)
                except TimeoutError:
                    continue
                except OSError:
                    return None
                if not data:
                    return None
                buffer.extend(data)
            line, _, rest = bytes(buffer).partition(b"\r\n")
            buffer[:] = rest
            return line

        def read_exact(n: int) -> bytes | None:
            while len(buffer) < n + 2:
                if self._stop.is_set():
                    return None
                try:
                    data = sock.recv(65536)
                except TimeoutError:
                    continue
                except OSError:
                    return None
                if not data:
                    return None
                buffer.extend(data)
            out = bytes(buffer[:n])
            del buffer[:n + 2]
            return out

        try:
            while True:
                header = read_line()
                if header is None or not header.startswith(b"*"):
                    return
                command: list[bytes] = []
                for _ in range(int(header[1:])):
                    size = read_line()
                    item = read_exact(int(size[1:])) if size is not None and size.startswith(b"$") else None
                    if item is None:
                        return
                    command.append(item)
                if not self._resp_command(sock, command):
                    return
        finally:
            with self._lock:
                self._resp_sockets.discard(sock)
            sock.close()

    def _resp_command(self, sock: socket.socket, command: list[bytes]) -> bool:
        name = command[0]
        if name == b"CLIENT":
            sock.sendall(b"+OK\r\n")
            return True
        if name == b"QUIT":
            sock.sendall(b"+OK\r\n")
            return False
        if name == b"PING":
            self._record("resp", "ping", None, None)
            sock.sendall(b"+PONG\r\n")
            return True
        text = name.decode("utf-8", "replace")
        node_name, _, op = text.partition(".")
        if text in ("add_node", "remove_node"):
            node_name, op = "", text
        elif node_name not in self.nodes or op not in ("initialize", "inference", "get_status"):
            sock.sendall(b"-INVALID_COMMAND\r\n")
            return True
        try:
            args = mp_unpack(command[1]) if len(command) > 1 else {}
        except Exception:
            sock.sendall(b"-INVALID_ARGS\r\n")
            return True
        self._record("resp", op, node_name or (args.get("node_name") if isinstance(args, dict) else None), args)
        if len(command) > 1 and not args:
            return True  # RoboML writes nothing for an empty argument map
        fault = self._take_fault(op)
        if fault is not None and fault.kind == "hang" and self._hang(fault):
            return False
        if fault is not None and fault.kind == "die":
            return False
        try:
            result = self._resp_execute(node_name, op, args, fault)
            reply = b"+OK\r\n" if not result else b"$%d\r\n%b\r\n" % (len(result), result)
        except ValidationError as exc:
            details = ";".join(f"{i}: {json.dumps(e['type'])} {json.dumps(e['loc'])} {json.dumps(e['msg'])}"
                               for i, e in enumerate(exc.errors))
            reply = f"-VALIDATION_ERROR {details}\r\n".encode()
        except LookupError:
            reply = b"-ERR Error loading the extension. Please check the server logs.\r\n"
        except Exception as exc:
            reply = f"-UNEXPECTED_ERROR {json.dumps(str(exc))}\r\n".encode()
        with contextlib.suppress(OSError):
            sock.sendall(reply)
        return True

    def _resp_execute(self, node_name: str, op: str, args: dict[str, Any], fault: _Fault | None) -> bytes | None:
        if op == "add_node":
            if set(args) != {"node_name", "node_model"}:
                raise ValidationError([{"type": "missing_argument", "loc": ["node_name"], "msg": "Missing"}])
            answer = self._add_node(args["node_name"], args["node_model"])
            if "warning" in answer:
                return mp_pack(f"Warning: {answer['warning']}")
            return mp_pack(["add_node", "remove_node"] + [f"{n}.{m}" for n in self.nodes
                                                         for m in ("get_status", "inference", "initialize")])
        if op == "remove_node":
            if args.get("node_name") not in self.nodes:
                raise ValueError(f"Node with name {args.get('node_name')} does not exist.")
            del self.nodes[args["node_name"]]
            return mp_pack(["add_node", "remove_node"])
        node = self.nodes[node_name]
        if op == "get_status":
            return mp_pack(node.status)
        if op == "initialize":
            node.initialize(args)
            return None
        if fault is not None and fault.kind == "error":
            raise RuntimeError(fault.message)
        if fault is not None and fault.kind == "bad_frame":
            return b"\xc1 not msgpack"
        result, tokens = node.infer(args)
        if tokens is not None:
            raise TypeError("can not serialize 'async_generator' object")
        return mp_pack(result)
