"""The MCP client's Streamable HTTP replies, bounded after decompression (``McpServerSpec.max_reply_bytes``).

The official SDK reads a JSON reply whole (``response.aread()``) and an SSE reply for as long as
the server keeps sending, through an httpx2 client that inflates ``gzip`` without bound: 200 KB
from a hostile server can become 200 MiB in memory before ``max_result_chars`` trims the text.
:func:`bounded_streamable_http` is the SDK's ``streamable_http_client`` over an httpx2 client of
our own (the SDK's timeouts, proxies from the environment), whose response hook gives every
response, before its body is read, the bounded decoder of
:mod:`agents_core.clients.reply_limit` (zlib's ``max_length``: never more than the limit is
inflated). What one response may carry after decompression is ``max_reply_bytes``: a JSON reply,
or every event of one SSE stream together (the answer to one request with its notifications; the
server's GET stream, which the SDK reopens at most twice in a row). One SSE event may be as large.

Past the limit the read raises :class:`McpReplyTooLargeError`, which is both an httpx2
``StreamError`` and an ``SSEError``: the two the SDK turns into a JSON-RPC error for the request
waiting on that response, so the call fails with our message (naming the server, its URL and the
limit) instead of hanging until its timeout or tearing the connection down; the connection stays
usable. The socket is closed there, so an endless stream is no longer read.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import AsyncIterator
from typing import Any

import httpx2

from ..clients.reply_limit import ACCEPT_ENCODING, BoundedDecoder, ReplyBudget, ReplyTooLargeError, bounded_decoder
from ..errors import ProtocolError

__all__ = ["McpReplyError", "McpReplyTooLargeError", "bounded_streamable_http"]

#: The SDK's own defaults for its HTTP client (``create_mcp_http_client``): 30 s, 300 s to read a stream.
_TIMEOUT = httpx2.Timeout(30.0, read=300.0)


class McpReplyError(ProtocolError, httpx2.SSEError, httpx2.StreamError):
    """An MCP server's reply that cannot be read within its bounds (damaged, or in an unknown encoding)."""


class McpReplyTooLargeError(ReplyTooLargeError, McpReplyError):
    """An MCP server's reply (after decompression) is larger than its entry's ``max_reply_bytes``."""


def _as_mcp_error(exc: ProtocolError) -> McpReplyError:
    kind = McpReplyTooLargeError if isinstance(exc, ReplyTooLargeError) else McpReplyError
    return kind(str(exc))


class _BoundedStream(httpx2.AsyncByteStream):
    """A response body giving the decoded bytes of ``stream`` through ``decoder``, or ``refused`` at once."""

    def __init__(self, stream: Any, decoder: BoundedDecoder | None, refused: McpReplyError | None) -> None:
        self._stream, self._decoder, self._refused = stream, decoder, refused

    async def __aiter__(self) -> AsyncIterator[bytes]:
        if self._refused is not None or self._decoder is None:
            raise self._refused or McpReplyError("no decoder")
        try:
            async for raw in self._stream:
                out = self._decoder.decode(raw)
                if out:
                    yield out
            tail = self._decoder.flush()
        except ProtocolError as exc:
            raise _as_mcp_error(exc) from None
        if tail:
            yield tail

    async def aclose(self) -> None:
        await self._stream.aclose()


def _bounding_hook(limit: int, label: str) -> Any:
    """An httpx2 response hook giving each response's body a fresh :class:`ReplyBudget` of ``limit`` bytes.

    httpx2 runs it before anyone reads the body, on every response (a redirect's too).
    """

    async def bound(response: httpx2.Response) -> None:
        budget = ReplyBudget(limit, f"{label}: {response.request.method}")
        decoder: BoundedDecoder | None = None
        refused: McpReplyError | None = None
        try:
            decoder = bounded_decoder(response.headers, budget)
        except ProtocolError as exc:
            # Raised when the body is read, where the SDK answers the waiting request with it.
            refused = _as_mcp_error(exc)
            for name in ("content-encoding", "content-length"):
                if name in response.headers:
                    del response.headers[name]
        response.stream = _BoundedStream(response.stream, decoder, refused)

    return bound


class _OneLineRefusals(logging.Filter):
    """The SDK logs a traceback for a JSON reply it could not read: ours get one line instead."""

    def filter(self, record: logging.LogRecord) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        if isinstance(exc, McpReplyError):
            record.msg, record.args, record.exc_info, record.exc_text = "%s", (str(exc),), None, None
            record.levelno, record.levelname = logging.WARNING, "WARNING"
        return True


_SDK_LOGGER = logging.getLogger("mcp.client.streamable_http")
if not any(isinstance(f, _OneLineRefusals) for f in _SDK_LOGGER.filters):
    _SDK_LOGGER.addFilter(_OneLineRefusals())


@contextlib.asynccontextmanager
async def bounded_streamable_http(url: str, *, name: str, max_reply_bytes: int) -> AsyncIterator[Any]:
    """The SDK's Streamable HTTP transport to ``url``, each reply bounded at ``max_reply_bytes`` (see above)."""
    from mcp.client.streamable_http import streamable_http_client  # noqa: PLC0415  (the mcp extra)

    hook = _bounding_hook(max_reply_bytes, f"MCP server {name!r} ({url})")
    http = httpx2.AsyncClient(timeout=_TIMEOUT, headers={"accept-encoding": ACCEPT_ENCODING},
                              event_hooks={"response": [hook]})
    async with http, streamable_http_client(url, http_client=http, max_sse_event_size=max_reply_bytes) as streams:
        yield streams
