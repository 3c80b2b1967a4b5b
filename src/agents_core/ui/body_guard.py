"""``BodyGuard``: ASGI middleware that reads each HTTP request body up front, bounded three ways.

uvicorn has no timeout for a request body and no limit on how many are read at once, so without
this a client that starts a chunked body and never ends it holds its buffers forever, and twenty
such clients hold hundreds of megabytes of the robot's own process. Here every body is:

- **bounded in size**: a declared ``Content-Length`` past ``max_bytes`` is refused (413) before
  anything is read, a chunked body as soon as it passes it;
- **bounded in time**: it must arrive in full within ``timeout`` seconds (408);
- **bounded in number**: at most ``max_bodies`` requests with a body are read or handled at once;
  past that a request is refused at once (503) rather than queued.

Refusals carry ``Connection: close``, so uvicorn closes the socket instead of waiting for the rest
of a body nobody will read. The endpoints then read the (already complete) body from memory.
"""

from __future__ import annotations

import json
from collections.abc import Awaitable, Callable, MutableMapping
from typing import Any

import anyio

__all__ = ["BodyGuard"]

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]


class _Disconnected(Exception):
    """The client went away while its body was being read."""


class BodyGuard:
    """Wraps ``app``: HTTP request bodies are read here, within ``max_bytes``, ``timeout`` and ``max_bodies``.

    :attr:`refused` counts the requests refused by each rule (``size``, ``time``, ``busy``).
    """

    def __init__(self, app: ASGIApp, *, max_bytes: int, timeout: float, max_bodies: int,
                 refused: dict[str, int] | None = None) -> None:
        self.app = app
        self.max_bytes = max_bytes
        self.timeout = timeout
        self.max_bodies = max_bodies
        #: Requests with a body being read or handled now (on the event loop: no lock needed).
        self.active = 0
        #: Refusals by rule; pass a mapping to share the counts (the UI's health reports them).
        self.refused = refused if refused is not None else {}
        for rule in ("size", "time", "busy"):
            self.refused.setdefault(rule, 0)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or not _has_body(scope):
            await self.app(scope, receive, send)
            return
        declared = _header(scope, b"content-length")
        if declared is not None:
            if not declared.isdigit():
                await _refuse(send, 400, "Content-Length is not a number")
                return
            if int(declared) > self.max_bytes:
                self.refused["size"] += 1
                await _refuse(send, 413, f"the body is {int(declared)} bytes; the limit is {self.max_bytes} bytes")
                return
        if self.active >= self.max_bodies:
            self.refused["busy"] += 1
            await _refuse(send, 503, f"{self.max_bodies} requests with a body are in progress; try again shortly",
                          retry_after=1)
            return
        self.active += 1
        try:
            try:
                with anyio.fail_after(self.timeout):
                    body = await self._read(receive)
            except TimeoutError:
                self.refused["time"] += 1
                await _refuse(send, 408, f"the request body did not arrive within {self.timeout:g} s")
                return
            except _Disconnected:
                return
            if body is None:
                self.refused["size"] += 1
                await _refuse(send, 413, f"the body is longer than the limit of {self.max_bytes} bytes")
                return
            holder = [body]
            del body  # the replay hands it over and lets go of it: one copy alive, not two
            await self.app(scope, _replay(holder, receive), send)
        finally:
            self.active -= 1

    async def _read(self, receive: Receive) -> bytes | None:
        """The whole body, or None as soon as it passes ``max_bytes``."""
        body = bytearray()
        while True:
            message = await receive()
            if message["type"] == "http.disconnect":
                raise _Disconnected
            body += message.get("body", b"")
            if len(body) > self.max_bytes:
                return None
            if not message.get("more_body", False):
                return bytes(body)


def _has_body(scope: Scope) -> bool:
    return _header(scope, b"content-length") not in (None, "0") or _header(scope, b"transfer-encoding") is not None


def _header(scope: Scope, name: bytes) -> str | None:
    for key, value in scope.get("headers", ()):
        if key.lower() == name:
            return bytes(value).decode("latin-1").strip()
    return None


def _replay(holder: list[bytes], receive: Receive) -> Receive:
    """A ``receive`` that gives the body in ``holder`` once, then waits on the real one (for a disconnect)."""

    async def replay() -> Message:
        if holder:
            return {"type": "http.request", "body": holder.pop(), "more_body": False}
        return await receive()

    return replay


async def _refuse(send: Send, status: int, message: str, retry_after: int | None = None) -> None:
    payload = json.dumps({"error": message}).encode()
    headers = [(b"content-type", b"application/json"), (b"content-length", str(len(payload)).encode()),
               (b"connection", b"close")]
    if retry_after is not None:
        headers.append((b"retry-after", str(retry_after).encode()))
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": payload, "more_body": False})
