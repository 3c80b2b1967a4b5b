"""Whole-call deadlines: a client call is bounded from connect to last byte, streams included.

A socket timeout bounds one read, not a call: a server that answers one byte per second, or that
sends SSE keep-alive comments (``": ping"``) forever, never trips it. Every client call therefore
runs under a :class:`CallWatch`, which holds a monotonic deadline (the client's
``inference_timeout``, or the timeout of that operation) and, for streams, the time allowed until
the first chunk and between chunks. Two things enforce it:

* the code reading an answer calls :meth:`CallWatch.check` between pieces (lines, frames), and
  passes :meth:`CallWatch.wait_seconds` as the timeout of each blocking read where it can;
* a single watchdog thread per process fires when the current limit passes while a read is still
  blocked, and runs the watch's *abort* action, which shuts the connection's socket down: the
  blocked read returns at once, and the error it raises is reported as
  :class:`~agents_core.errors.InferenceTimeoutError` because the watch has fired.

Chunks are what a stream yields to its consumer (text pieces): keep-alive comments, empty lines
and other bytes that carry no answer never reset the chunk timers, and nothing resets the
deadline. :class:`BoundedHTTP` applies this to httpx: it learns the socket of each request (from
httpx's ``trace`` extension when it connects, or from the response once headers arrived) so the
watchdog can cut it.
"""

from __future__ import annotations

import contextlib
import heapq
import itertools
import math
import os
import socket
import threading
import time
import weakref
from collections.abc import Callable, Mapping
from typing import Any

import httpx

from ..errors import ConfigError, InferenceTimeoutError
from .reply_limit import ACCEPT_ENCODING, DEFAULT_MAX_REPLY_BYTES, ReplyBudget, bound_reply

__all__ = ["BoundedHTTP", "CallWatch", "check_seconds", "shutdown_socket"]

#: Seconds a TCP connect may take at most (a smaller remaining deadline wins).
DEFAULT_CONNECT_TIMEOUT = 10.0


def check_seconds(owner: str, name: str, value: Any, *, optional: bool = False) -> float | None:
    """``value`` as seconds: a finite number > 0 (not a bool), or None when ``optional``.

    Raises :class:`~agents_core.errors.ConfigError` naming ``owner`` and ``name`` otherwise.
    """
    if value is None and optional:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) or value <= 0:
        extra = " or None" if optional else ""
        raise ConfigError(f"{owner}: {name} must be > 0 s and finite{extra}, got {value!r}")
    return float(value)


def shutdown_socket(sock: socket.socket) -> None:
    """Shut ``sock`` down in both directions, which wakes a thread blocked reading or writing it.

    ``close()`` alone does not wake such a thread on Linux. The plain socket method is used even
    for a TLS socket, whose own ``shutdown`` also drops its TLS state under the reading thread.
    """
    with contextlib.suppress(OSError, ValueError):
        socket.socket.shutdown(sock, socket.SHUT_RDWR)


# -- the watchdog ---------------------------------------------------------------------------------


class _Alarm:
    __slots__ = ("callback", "cancelled", "when")

    def __init__(self, when: float, callback: Callable[[_Alarm], None]) -> None:
        self.when = when
        self.callback = callback
        self.cancelled = False


class _Watchdog:
    """One daemon thread per process running alarms at monotonic times (a heap, no thread per call)."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._heap: list[tuple[float, int, _Alarm]] = []
        self._order = itertools.count()
        self._thread: threading.Thread | None = None
        self._pid = 0

    def schedule(self, when: float, callback: Callable[[_Alarm], None]) -> _Alarm:
        alarm = _Alarm(when, callback)
        with self._cond:
            # A forked child inherits the heap but not the thread: start its own.
            if self._thread is None or self._pid != os.getpid() or not self._thread.is_alive():
                self._pid = os.getpid()
                self._thread = threading.Thread(target=self._run, name="agents-core-deadlines", daemon=True)
                self._thread.start()
            heapq.heappush(self._heap, (when, next(self._order), alarm))
            self._cond.notify()
        return alarm

    def _run(self) -> None:
        while True:
            with self._cond:
                while True:
                    while self._heap and self._heap[0][2].cancelled:
                        heapq.heappop(self._heap)
                    if not self._heap:
                        self._cond.wait()
                        continue
                    wait = self._heap[0][0] - time.monotonic()
                    if wait <= 0:
                        alarm = heapq.heappop(self._heap)[2]
                        break
                    self._cond.wait(wait)
            # Outside the heap's lock: a callback may schedule the next alarm.
            with contextlib.suppress(Exception):
                alarm.callback(alarm)


_WATCHDOG = _Watchdog()


# -- one call -------------------------------------------------------------------------------------


class CallWatch:
    """The limits of one client call: a whole-call deadline and, for streams, chunk timers.

    :param seconds: the whole call's budget (connect to last byte).
    :param label: names the client and operation in the timeout error.
    :param first_chunk: seconds from the start of the call to the first chunk (None: only the
        deadline bounds it).
    :param between_chunks: seconds the consumer may wait for each later chunk (None: only the
        deadline).
    :param what: the setting that gave ``seconds``, named in the error ("inference_timeout").

    The watch is armed at construction. :meth:`close` ends it (idempotent); a closed watch never
    runs its abort action again.
    """

    def __init__(self, seconds: float, label: str, *, first_chunk: float | None = None,
                 between_chunks: float | None = None, what: str = "inference_timeout") -> None:
        self.label = label
        self.seconds = float(seconds)
        self.what = what
        self.first_chunk = first_chunk
        self.between_chunks = between_chunks
        self.start = time.monotonic()
        self.deadline = self.start + self.seconds
        self.chunks = 0
        #: Which limit fired ("deadline", "first chunk", "between chunks"), None while none has.
        self.fired: str | None = None
        self._lock = threading.Lock()
        self._abort: Callable[[], None] | None = None
        self._alarm: _Alarm | None = None
        self._closed = False
        self._limit_at = self.deadline
        self._limit = "deadline"
        if first_chunk is not None:
            self._set_limit(self.start + first_chunk, "first chunk")
        else:
            self._set_limit(self.deadline, "deadline")

    # -- limits -----------------------------------------------------------------------------------

    def _set_limit(self, at: float, name: str) -> None:
        if at >= self.deadline:
            at, name = self.deadline, "deadline"
        with self._lock:
            if self._closed:
                return
            self._limit_at, self._limit = at, name
            # A later limit keeps the current alarm (it re-arms itself when it fires early); an
            # earlier one needs a new alarm.
            if self._alarm is None or self._alarm.when > at:
                if self._alarm is not None:
                    self._alarm.cancelled = True
                self._alarm = _WATCHDOG.schedule(at, self._on_alarm)

    def _on_alarm(self, alarm: _Alarm) -> None:
        with self._lock:
            if self._closed or alarm is not self._alarm:
                return
            if time.monotonic() < self._limit_at:
                self._alarm = _WATCHDOG.schedule(self._limit_at, self._on_alarm)
                return
            self._alarm = None
            self.fired = self._limit
            # Under the lock: close() waits for it, so a connection handed back to a pool after
            # close() is never cut by a late alarm.
            if self._abort is not None:
                with contextlib.suppress(Exception):
                    self._abort()

    def set_abort(self, abort: Callable[[], None] | None) -> None:
        """What to run when a limit passes during a blocked read (cut the connection); runs now if one did."""
        with self._lock:
            self._abort = abort
            fire_now = self.fired is not None and abort is not None and not self._closed
            if fire_now and abort is not None:
                with contextlib.suppress(Exception):
                    abort()

    def before_chunk(self) -> None:
        """The consumer asks for the next chunk: start that chunk's timer (raises if a limit passed)."""
        if self.chunks and self.between_chunks is not None:
            self._set_limit(time.monotonic() + self.between_chunks, "between chunks")
        self.check()

    def after_chunk(self) -> None:
        """A chunk arrived: only the deadline runs until the consumer asks for the next one."""
        self.chunks += 1
        self._set_limit(self.deadline, "deadline")

    def remaining(self) -> float:
        """Seconds left before the whole-call deadline (may be negative)."""
        return self.deadline - time.monotonic()

    def wait_seconds(self) -> float:
        """Seconds a blocking read may wait now: until the current limit (never negative)."""
        return max(0.0, self._limit_at - time.monotonic())

    def passed(self) -> bool:
        """Whether the current limit has passed (or fired)."""
        return self.fired is not None or time.monotonic() >= self._limit_at

    def check(self) -> None:
        """Raise :class:`~agents_core.errors.InferenceTimeoutError` if the current limit has passed."""
        if self.passed():
            if self.fired is None:
                self.fired = self._limit
            raise self.error()

    def error(self) -> InferenceTimeoutError:
        """The typed error for the limit that passed, with the times involved."""
        elapsed = time.monotonic() - self.start
        limit = self.fired or self._limit
        if limit == "first chunk":
            why = f"no first chunk within stream_first_chunk_timeout {self.first_chunk:g} s"
        elif limit == "between chunks":
            why = f"no chunk for stream_chunk_timeout {self.between_chunks:g} s"
        else:
            why = f"not finished within {self.what} {self.seconds:g} s"
        return InferenceTimeoutError(f"{self.label} timed out: {why} (after {elapsed:.2f} s)")

    def httpx_timeout(self, connect: float = DEFAULT_CONNECT_TIMEOUT) -> httpx.Timeout:
        """Per-operation httpx timeouts that never outlast the current limit (the watchdog does the rest)."""
        wait = max(self.wait_seconds(), 0.001)
        return httpx.Timeout(wait, connect=min(connect, wait))

    def close(self) -> None:
        """End the watch: no abort runs after this returns."""
        with self._lock:
            self._closed = True
            self._abort = None
            if self._alarm is not None:
                self._alarm.cancelled = True
                self._alarm = None


# -- httpx ----------------------------------------------------------------------------------------


def _timed_out(watch: CallWatch, exc: BaseException) -> bool:
    """Whether ``exc`` comes from the watch's limit (the watchdog cut the socket, or a read timed out at it)."""
    return watch.fired is not None or (isinstance(exc, httpx.TimeoutException | TimeoutError) and watch.passed())


class _Exchange:
    """The socket of one request, learnt as early as httpx tells it."""

    def __init__(self, owner: BoundedHTTP, watch: CallWatch) -> None:
        self.owner = owner
        self.watch = watch
        self.socket: socket.socket | None = None
        self._released = False

    def trace(self, event: str, info: Mapping[str, Any]) -> None:
        # httpx's "trace" request extension: connect_tcp / start_tls hand back the new stream.
        if event.endswith(".complete"):
            self.learn(info.get("return_value"))

    def learn(self, stream: Any) -> None:
        get = getattr(stream, "get_extra_info", None)
        sock = get("socket") if callable(get) else None
        if isinstance(sock, socket.socket) and sock is not self.socket:
            self.owner._claim(sock, self.socket)
            self.socket = sock

    def abort(self) -> None:
        if self.socket is not None:
            shutdown_socket(self.socket)
        else:
            # A reused connection whose socket this call has not seen yet (headers pending):
            # cut every connection of the pool no other call is using.
            self.owner._shutdown_unclaimed()

    def release(self) -> None:
        if not self._released:
            self._released = True
            self.owner._claim(None, self.socket)


class BoundedHTTP:
    """An ``httpx.Client`` whose every request runs under a :class:`CallWatch`.

    :param base_url: prefix of every request URL.
    :param headers: sent with every request (an ``Authorization`` header, ...).
    :param connect_timeout: the most a TCP connect may take (a smaller remaining deadline wins).
    :param max_reply_bytes: the most bytes one reply's body may hold after decompression, a
        streamed one included (:mod:`.reply_limit`); past it the read stops with
        :class:`~agents_core.clients.reply_limit.ReplyTooLargeError`.
    """

    def __init__(self, base_url: str, *, headers: Mapping[str, str] | None = None,
                 connect_timeout: float = DEFAULT_CONNECT_TIMEOUT,
                 max_reply_bytes: int = DEFAULT_MAX_REPLY_BYTES) -> None:
        # The transport is ours so that close() can close its pool again once the requests that
        # were in flight at close() have ended: httpx returns their connections to the pool after
        # the client closed it, and nothing would close them (a leaked socket, a ResourceWarning).
        self._transport = httpx.HTTPTransport()
        self.client = httpx.Client(base_url=base_url, headers={"Accept-Encoding": ACCEPT_ENCODING, **(headers or {})},
                                   timeout=connect_timeout, transport=self._transport)
        self.connect_timeout = connect_timeout
        self.max_reply_bytes = max_reply_bytes
        self._lock = threading.Lock()
        self._sockets: weakref.WeakValueDictionary[int, socket.socket] = weakref.WeakValueDictionary()
        self._claimed: dict[int, int] = {}
        self._in_flight = 0
        self._closing = False

    # -- socket bookkeeping ---------------------------------------------------------------------

    def _claim(self, new: socket.socket | None, old: socket.socket | None) -> None:
        with self._lock:
            if old is not None and self._claimed.get(id(old), 0) > 0:
                self._claimed[id(old)] -= 1
                if not self._claimed[id(old)]:
                    del self._claimed[id(old)]
            if new is not None:
                self._sockets[id(new)] = new
                self._claimed[id(new)] = self._claimed.get(id(new), 0) + 1

    def _shutdown_unclaimed(self) -> None:
        with self._lock:
            idle = [s for key, s in list(self._sockets.items()) if key not in self._claimed]
        for sock in idle:
            shutdown_socket(sock)

    # -- requests -------------------------------------------------------------------------------

    def open(self, method: str, url: str, watch: CallWatch, **kwargs: Any) -> httpx.Response:
        """Send a request and read the response headers; the body is left to read (``stream=True``).

        The watch's abort action cuts this response's connection from now on; close the
        response, then the watch, when done. Raises the watch's timeout error when it fired.
        """
        exchange = _Exchange(self, watch)
        watch.check()
        watch.set_abort(exchange.abort)
        extensions = {"trace": exchange.trace}
        self._begin()
        try:
            request = self.client.build_request(method, url, timeout=watch.httpx_timeout(self.connect_timeout),
                                                extensions=extensions, **kwargs)
            response = self.client.send(request, stream=True)
        except Exception as exc:
            exchange.release()
            self._end()
            if _timed_out(watch, exc):
                raise watch.error() from exc
            raise
        exchange.learn(response.extensions.get("network_stream"))
        # Released with the response: the connection goes back to the pool.
        original_close = response.close
        try:
            bound_reply(response, ReplyBudget(self.max_reply_bytes, watch.label))
        except BaseException:
            original_close()
            exchange.release()
            self._end()
            raise

        ended = False

        def close() -> None:
            nonlocal ended
            try:
                original_close()
            finally:
                exchange.release()
                if not ended:
                    ended = True
                    if self._closing and exchange.socket is not None:
                        # Connected after close() emptied the pool: httpcore no longer lists this
                        # connection, so closing the pool again would not reach its socket.
                        shutdown_socket(exchange.socket)
                        exchange.socket.close()
                    self._end()

        response.close = close  # type: ignore[method-assign]
        return response

    def request(self, method: str, url: str, *, seconds: float, label: str, what: str = "inference_timeout",
                **kwargs: Any) -> httpx.Response:
        """Send a request and read the whole answer within ``seconds`` (connect to last byte).

        :param label: names the client and operation in a timeout error.
        :param what: the setting that gave ``seconds``, named in a timeout error.
        :raises InferenceTimeoutError: when the answer is not complete in time.
        """
        watch = CallWatch(seconds, label, what=what)
        try:
            response = self.open(method, url, watch, **kwargs)
        except BaseException:
            watch.close()
            raise
        try:
            response.read()
            if watch.fired is not None:
                # A body delimited by the connection's close ends "cleanly" when the watchdog cuts
                # the socket: what was read is a truncated answer, and the cause is the deadline.
                raise watch.error()
        except InferenceTimeoutError:
            raise
        except Exception as exc:
            if _timed_out(watch, exc):
                raise watch.error() from exc
            raise
        finally:
            # The watch first: its abort must never cut a connection already back in the pool.
            watch.close()
            response.close()
        return response

    def _begin(self) -> None:
        with self._lock:
            self._in_flight += 1

    def _end(self) -> None:
        with self._lock:
            self._in_flight -= 1
            last = self._closing and self._in_flight == 0
        if last:
            self._transport.close()  # the connections those requests gave back after close()

    def close(self) -> None:
        """Close the connection pool; requests in flight are cut, and their connections closed when they end."""
        with self._lock:
            self._closing = True
            busy = self._in_flight > 0
            in_use = list(self._sockets.values()) if busy else []
        self.client.close()
        for sock in in_use:
            shutdown_socket(sock)

    @property
    def is_closed(self) -> bool:
        """Whether :meth:`close` was called."""
        return self.client.is_closed
