"""``RoboMLWSClient``: RoboML inference over its WebSocket endpoint, lifecycle over HTTP.

Frames and their meaning are described in :mod:`agents_core.clients.roboml_protocol`. RoboML's WebSocket
replies carry no request id, so replies are matched to requests by order: the client keeps one
connection with at most one request in flight on it (a lock), and throws the connection away
whenever a reply may be left unread (a timeout, a stream closed early, an error), so a late
reply can never be read as the answer to the next request.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Iterator, MutableMapping
from typing import Any, ClassVar

from websockets.exceptions import ConnectionClosed, InvalidStatus, WebSocketException
from websockets.protocol import State
from websockets.sync.client import ClientConnection, connect

from ..errors import (
    ClientConnectionError,
    HTTPStatusError,
    InferenceError,
    InferenceTimeoutError,
    ModelClientError,
    ProtocolError,
)
from .deadline import CallWatch, shutdown_socket
from .payloads import ChunkStream
from .reply_limit import ReplyBudget, ReplyTooLargeError
from .roboml_http import RoboMLHTTPClient
from .roboml_protocol import (
    RESPONSE_ENDED,
    ROBOML_NODE_MODELS,
    WS_CHUNK_SIZE,
    build_roboml_input,
    normalize_result,
    packb,
    retry_connect,
    unpackb,
)

__all__ = ["RoboMLWSClient"]

# Close codes a server sends when it is going away or done, as opposed to reporting an error.
_NORMAL_CLOSE = {1000, 1001}


class RoboMLWSClient(RoboMLHTTPClient):
    """A model served by RoboML, with inference over a WebSocket (node lifecycle over HTTP).

    Same parameters as :class:`~agents_core.clients.roboml_http.RoboMLHTTPClient`; ``port`` is
    RoboML's HTTP port, which also serves ``/<node>/ws_inference``.

    The connection opens on the first inference and reopens after it drops (``connect_attempts``
    tries). ``inference()`` with ``stream: True`` returns a ChunkStream of tokens; for a
    component's streaming thread, :meth:`pump_once` and :meth:`serve_queues` move requests from
    its ``req_queue`` to replies in its ``resp_queue``.
    """

    #: Components start their streaming thread for clients that say so.
    is_websocket: ClassVar[bool] = True
    #: Seconds to wait for the next frame of a reply RoboML split at 1 MiB (it sends no end marker).
    continuation_grace: ClassVar[float] = 2.0
    #: Largest frame accepted (RoboML's frames are at most 1 MiB, or 4 MiB of UTF-8 for text).
    max_frame_size: ClassVar[int] = 8 * 1024 * 1024

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._ws: ClientConnection | None = None
        self._ws_lock = threading.Lock()  # guards self._ws
        self._request_lock = threading.Lock()  # one request in flight on the connection

    @property
    def ws_url(self) -> str:
        """The node's WebSocket endpoint."""
        return f"ws://{self.host}:{self.port}/{self.node_name}/ws_inference"

    @property
    def connected(self) -> bool:
        """Whether a WebSocket connection is open now."""
        ws = self._ws
        return ws is not None and ws.protocol.state is State.OPEN

    # -- connection -------------------------------------------------------------------------

    def _ws_error(self, exc: BaseException, what: str) -> ModelClientError:
        label = f"{self._label()}: {what}"
        if isinstance(exc, ModelClientError):
            return exc
        if isinstance(exc, ConnectionClosed):
            if exc.sent is not None and exc.sent.code == 1009:  # we closed it: a frame over max_size
                limit = min(self.max_frame_size, self.max_reply_bytes)
                return ReplyTooLargeError(f"{label}: a frame from {self.ws_url} is larger than {limit} bytes "
                                          f"(max_reply_bytes={self.max_reply_bytes}); refused")
            close = exc.rcvd
            if close is not None and close.code not in _NORMAL_CLOSE:
                # RoboML closes with 1007 and the error as reason when the input is invalid or
                # the model raised.
                return InferenceError(f"{label}: RoboML closed the connection with code {close.code}: {close.reason}")
            return ClientConnectionError(f"{label}: the connection closed before the reply ended ({exc})")
        if isinstance(exc, InvalidStatus):
            status = exc.response.status_code
            body = exc.response.body.decode("utf-8", "replace")[:300] if exc.response.body else ""
            return HTTPStatusError(f"{label}: RoboML refused the WebSocket with {status}: {body}", status=status)
        if isinstance(exc, TimeoutError):
            return InferenceTimeoutError(f"{label}: no reply within {self.inference_timeout} s")
        if isinstance(exc, OSError):
            return ClientConnectionError(f"{label}: cannot reach RoboML at {self.ws_url}: {exc}")
        if isinstance(exc, WebSocketException):
            return ProtocolError(f"{label}: {type(exc).__name__}: {exc}")
        return InferenceError(f"{label}: {type(exc).__name__}: {exc}")

    def _open_ws(self, watch: CallWatch | None = None) -> ClientConnection:
        with self._ws_lock:
            ws = self._ws
            if ws is not None and ws.protocol.state is State.OPEN:
                return ws
            self._ws = None
        if ws is not None:
            ws.close()  # dropped by the server: release its socket before reconnecting

        def attempt() -> ClientConnection:
            try:
                budget = float(self.inference_timeout) if watch is None else max(watch.wait_seconds(), 0.001)
                connecting = connect(self.ws_url, open_timeout=min(budget, 10.0),
                                     close_timeout=1.0, max_size=min(self.max_frame_size, self.max_reply_bytes),
                                     compression=None)  # images and audio do not compress; save the CPU
                # Entering the context is how every websockets version (12 to 17 and the coming
                # non-legacy connect()) hands over an open connection; _discard_ws closes it.
                return connecting.__enter__()
            except (OSError, TimeoutError, WebSocketException) as exc:
                raise self._ws_error(exc, "opening the WebSocket") from exc

        ws = retry_connect(attempt, attempts=self.connect_attempts, delay=self.connect_retry_delay,
                           retry_on=(ClientConnectionError,), logger=self.logger,
                           what=f"{self._label()}: opening the WebSocket")
        with self._ws_lock:
            self._ws = ws
        return ws

    def _discard_ws(self, ws: ClientConnection | None) -> None:
        with self._ws_lock:
            if ws is None or self._ws is ws:
                ws, self._ws = self._ws, None
        if ws is not None:
            ws.close()

    def _recv(self, ws: ClientConnection, timeout: float) -> str | bytes:
        try:
            return ws.recv(timeout=max(timeout, 0.0))
        except (ConnectionClosed, TimeoutError, OSError, WebSocketException) as exc:
            raise self._ws_error(exc, "inference") from exc

    def _ws_budget(self) -> ReplyBudget:
        return ReplyBudget(self.max_reply_bytes, f"{self._label()}: inference ({self.ws_url})")

    # -- inference --------------------------------------------------------------------------

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        payload, stream = build_roboml_input(self.node_model, inference_input, binary=True)
        frame = packb(payload)
        # The whole inference, waiting for the connection included, within inference_timeout.
        watch = self._watch("inference", stream=stream)
        if not self._request_lock.acquire(timeout=max(watch.wait_seconds(), 0.0)):
            watch.close()
            raise InferenceTimeoutError(f"{self._label()}: inference timed out: another request kept the "
                                        f"connection for more than {self.inference_timeout} s")
        handed_to_stream = False
        ws: ClientConnection | None = None
        try:
            ws = self._open_ws(watch)
            opened = ws
            # Reads time out by themselves; the watchdog cuts a send the server does not read.
            watch.set_abort(lambda: shutdown_socket(opened.socket))
            try:
                ws.send(frame)
            except (ConnectionClosed, OSError, WebSocketException) as exc:
                raise self._ws_error(exc, "sending the request") from exc
            if stream:
                chunks = self._stream_ws(ws, watch)
                handed_to_stream = True
                return {"output": chunks}
            return normalize_result(self.node_model, {"output": self._read_reply(ws, watch)}, self._label())
        except Exception as exc:
            self._discard_ws(ws)
            if watch.fired is not None or (isinstance(exc, TimeoutError) and watch.passed()):
                raise watch.error() from exc
            raise
        except BaseException:
            self._discard_ws(ws)
            raise
        finally:
            if not handed_to_stream:
                watch.close()
                self._request_lock.release()

    def _read_reply(self, ws: ClientConnection, watch: CallWatch) -> Any:
        deadline = time.monotonic() + watch.wait_seconds()
        budget = self._ws_budget()
        parts = [self._recv(ws, deadline - time.monotonic())]
        budget.add(len(parts[0]))
        # A frame of exactly WS_CHUNK_SIZE may be the first piece of a split reply.
        while len(parts[-1]) == WS_CHUNK_SIZE:
            try:
                part = self._recv(ws, min(self.continuation_grace, deadline - time.monotonic()))
            except InferenceTimeoutError:
                # Either the reply was exactly that long or its rest is late: the connection
                # can no longer be trusted to start the next reply cleanly.
                self._discard_ws(ws)
                break
            if type(part) is not type(parts[0]):
                raise ProtocolError(f"{self._label()}: inference: a split reply mixed text and binary frames")
            budget.add(len(part))
            parts.append(part)
        if isinstance(parts[0], str):
            return "".join(p for p in parts if isinstance(p, str))
        data = b"".join(p for p in parts if isinstance(p, bytes))
        # Bytes outputs (speech audio) come raw; every other non-text output is msgpack.
        return data if ROBOML_NODE_MODELS[self.node_model] == "text_to_speech" else unpackb(data)

    def _stream_ws(self, ws: ClientConnection, watch: CallWatch) -> ChunkStream[str]:
        ended = threading.Event()
        budget = self._ws_budget()

        def chunks() -> Iterator[str]:
            while True:
                # Until the current limit: the first chunk's, the next chunk's or the deadline.
                message = self._recv(ws, watch.wait_seconds())
                if not isinstance(message, str):
                    raise ProtocolError(f"{self._label()}: inference: a binary frame inside a token stream")
                if message == RESPONSE_ENDED:
                    ended.set()
                    return
                budget.add(len(message))  # the whole stream's characters, not one frame's
                yield message

        def release() -> None:
            try:
                if not ended.is_set():
                    self._discard_ws(ws)  # the rest of this reply would precede the next one
            finally:
                self._request_lock.release()

        return self._chunk_stream(chunks(), watch, f"{self._label()}: inference", on_close=release)

    # -- component streaming path -----------------------------------------------------------

    def pump_once(self, req_queue: queue.Queue[dict[str, Any]], resp_queue: queue.Queue[Any],
                  stop_event: threading.Event | None = None, wait: float = 0.0) -> bool:
        """Serve at most one request from ``req_queue`` into ``resp_queue``.

        The reply goes into ``resp_queue`` as the output's chunks (or the whole output when it
        does not stream), then one final item: :data:`~agents_core.clients.roboml_protocol.RESPONSE_ENDED`,
        or the typed :class:`~agents_core.errors.ModelClientError` if the request failed.
        Setting ``stop_event`` cuts a stream short (it still ends with RESPONSE_ENDED).

        :param wait: seconds to wait for a request (0: only take one that is already there).
        :returns: whether a request was taken.
        """
        try:
            request = req_queue.get(timeout=wait) if wait > 0 else req_queue.get_nowait()
        except queue.Empty:
            return False
        try:
            output = self.inference(request)["output"]
            if isinstance(output, ChunkStream):
                with output:
                    for chunk in output:
                        resp_queue.put(chunk)
                        if stop_event is not None and stop_event.is_set():
                            break
            else:
                resp_queue.put(output)
            resp_queue.put(RESPONSE_ENDED)
        except ModelClientError as exc:
            resp_queue.put(exc)
        return True

    def serve_queues(self, req_queue: queue.Queue[dict[str, Any]], resp_queue: queue.Queue[Any],
                     stop_event: threading.Event, poll: float = 0.001) -> None:
        """Run :meth:`pump_once` until ``stop_event`` is set (a component's streaming thread body)."""
        while not stop_event.is_set():
            self.pump_once(req_queue, resp_queue, stop_event, wait=poll)

    # -- shutdown ---------------------------------------------------------------------------

    def close(self) -> None:
        """Close the WebSocket and the HTTP connections (idempotent)."""
        self._discard_ws(None)
        super().close()
