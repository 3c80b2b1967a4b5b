"""Serving requests fairly and on time: per-owner request lanes and the caller's deadline.

Two promises every transport keeps for request/reply (component actions, parameter updates,
lifecycle transitions asked from outside):

- **One component's requests never delay another's.** Requests for a service owned by a
  component run on that component's own *lane* (a small pool of its own, created on first
  use); requests for services without an owner share one lane. A component busy for 20 s
  holds only its own lane.
- **A request whose caller gave up is not executed later.** The caller's timeout travels with
  the request (the reserved key :data:`CALLER_TIMEOUT_KEY` in the request map, seconds, added
  by ``Transport.request``); a request that waited in its lane longer than that is answered
  with an error instead of running, and a handler that runs can read the remaining time with
  :func:`request_deadline` (``Component.run_on_worker`` does, so an action queued behind a
  long step is skipped once its caller has stopped waiting).

A service created ``inline`` (a component's own services) promises that its handler returns by the
caller's deadline and does nothing slow itself (a component's action goes to the component's
worker, and the handler waits for it no longer than :func:`request_deadline`). Where the driver
serves requests in the caller's process (``local_requests``: memory), such a request from a thread
that is not serving a request already is answered on the caller's thread (:func:`answer_here`):
it then blocks only its caller, for no longer than the caller would have waited for the reply,
and saves a hand-off each way.
"""

from __future__ import annotations

import contextvars
import math
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, TypeVar

from ..errors import ConfigError, RemoteError, RequestTimeoutError
from ..support import bounded_json

__all__ = [
    "CALLER_TIMEOUT_KEY",
    "RequestLanes",
    "answer_here",
    "check_timeout",
    "json_call_reply",
    "on_lane",
    "request_deadline",
    "serve_with_caller_deadline",
    "with_caller_timeout",
]

R = TypeVar("R")

#: Reserved request-map key: how many seconds the caller waits for the reply.
CALLER_TIMEOUT_KEY = "_timeout_s"
#: The longest timeout a request may ask for (a day): larger values are almost surely a unit mistake.
MAX_TIMEOUT_S = 86_400.0

_received_at: contextvars.ContextVar[float | None] = contextvars.ContextVar("request_received_at", default=None)
_deadline: contextvars.ContextVar[float | None] = contextvars.ContextVar("request_deadline", default=None)


def check_timeout(timeout: Any, what: str) -> float:
    """``timeout`` as a float if it is a finite number of seconds > 0, else :class:`ConfigError`."""
    if isinstance(timeout, bool) or not isinstance(timeout, int | float) or not math.isfinite(timeout) \
            or not 0 < timeout <= MAX_TIMEOUT_S:
        raise ConfigError(f"{what}: timeout must be a finite number of seconds in (0, {MAX_TIMEOUT_S:g}], "
                          f"got {timeout!r}")
    return float(timeout)


def with_caller_timeout(payload: dict[str, Any], timeout: float) -> dict[str, Any]:
    """The request map to send: ``payload`` plus the caller's timeout under :data:`CALLER_TIMEOUT_KEY`."""
    if not isinstance(payload, dict):
        raise ConfigError(f"a request payload must be a dict, got {type(payload).__name__}")
    return {**payload, CALLER_TIMEOUT_KEY: timeout}


def request_deadline() -> float | None:
    """The monotonic time by which the caller of the request being served stops waiting, if known."""
    return _deadline.get()


def on_lane() -> bool:
    """True on a request lane's thread while it serves a request (a transport thread)."""
    return _received_at.get() is not None


def answer_here(name: str, serve: Callable[[dict[str, Any]], dict[str, Any]], payload: dict[str, Any],
                timeout: float) -> dict[str, Any]:
    """Serve a request to the ``inline`` service ``name`` on this thread (see the module docstring).

    ``serve`` is the service's handler wrapped by :func:`serve_with_caller_deadline`. Its errors
    reach the caller as a driver's ``call`` raises them: :class:`~agents_core.errors.RemoteError`
    for the handler's own failure, :class:`~agents_core.errors.RequestTimeoutError` for one that
    came once the caller's time was up (a lane's caller would have stopped waiting by then).
    """
    request = with_caller_timeout(payload, timeout)
    deadline = time.monotonic() + timeout
    try:
        return serve(request)
    except Exception as exc:
        if time.monotonic() >= deadline:
            raise RequestTimeoutError(f"request to {name!r} got no reply within {timeout:g} s") from exc
        raise RemoteError(f"{name!r} failed: {type(exc).__name__}: {exc}") from exc


def serve_with_caller_deadline(handler: Callable[[dict[str, Any]], R], request: dict[str, Any], what: str) -> R:
    """Run ``handler(request)`` unless its caller has already given up (see the module docstring).

    Takes :data:`CALLER_TIMEOUT_KEY` out of ``request``; the time the request was received is
    the moment its lane accepted it (or now, outside a lane).
    """
    timeout = request.pop(CALLER_TIMEOUT_KEY, None)
    received = _received_at.get()
    if received is None:
        received = time.monotonic()
    deadline = None
    if timeout is not None:
        timeout = check_timeout(timeout, what)
        deadline = received + timeout
        waited = time.monotonic() - received
        if waited >= timeout:
            raise RequestTimeoutError(f"{what}: not run, the caller's timeout of {timeout:g} s expired after "
                                      f"{waited:.2f} s in the queue")
    token = _deadline.set(deadline)
    try:
        return handler(request)
    finally:
        _deadline.reset(token)


class RequestLanes:
    """Thread pools by owner: requests of one owner queue only behind that owner's requests.

    :param name: thread-name prefix.
    :param shared_workers: threads of the lane for requests without an owner.
    :param workers_per_owner: threads of each owner's lane (a component serves its requests on
        its serial worker anyway; two threads let a quick one pass a slow one).
    """

    def __init__(self, name: str, *, shared_workers: int = 4, workers_per_owner: int = 2) -> None:
        if shared_workers < 1 or workers_per_owner < 1:
            raise ConfigError(f"request lanes {name!r}: worker counts must be at least 1")
        self._name = name
        self._workers_per_owner = workers_per_owner
        self._lock = threading.Lock()
        self._shared = ThreadPoolExecutor(max_workers=shared_workers, thread_name_prefix=f"{name}")
        self._lanes: dict[str, ThreadPoolExecutor] = {}
        self._closed = False

    def submit(self, owner: str | None, func: Callable[..., R], *args: Any) -> Future[R]:
        """Run ``func(*args)`` on ``owner``'s lane; raises RuntimeError once shut down."""
        received = time.monotonic()

        def run() -> R:
            token = _received_at.set(received)
            try:
                return func(*args)
            finally:
                _received_at.reset(token)

        with self._lock:
            if self._closed:
                raise RuntimeError(f"request lanes {self._name!r} are shut down")
            pool = self._shared if owner is None else self._lanes.get(owner)
            if pool is None:
                assert owner is not None
                pool = ThreadPoolExecutor(max_workers=self._workers_per_owner,
                                          thread_name_prefix=f"{self._name}:{owner}")
                self._lanes[owner] = pool
            return pool.submit(run)

    def shutdown(self) -> None:
        """Stop every lane; requests not started are dropped (their callers time out). Idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            pools = [self._shared, *self._lanes.values()]
        for pool in pools:
            pool.shutdown(wait=False, cancel_futures=True)


def json_call_reply(name: str, success: bool, error: str, response_json: str) -> dict[str, Any]:
    """The reply map of a ``JsonCall`` service's response (a middleware's typed services carry JSON this way).

    :raises RemoteError: naming service ``name``, when the server reported a failure, or its reply does not
        decode within :data:`~agents_core.support.bounded_json.REQUEST_JSON_LIMITS`, or is not a JSON object.
    """
    if not success:
        raise RemoteError(f"{name!r} failed: {error}")
    try:
        reply = bounded_json.loads(response_json or "{}", bounded_json.REQUEST_JSON_LIMITS)
    except bounded_json.InvalidJsonError as exc:
        raise RemoteError(f"{name!r} sent a reply that does not decode: {exc}") from None
    if not isinstance(reply, dict):
        raise RemoteError(f"{name!r} replied with a {type(reply).__name__}, not a JSON object")
    return reply
