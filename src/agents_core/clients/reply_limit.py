"""A reply's size bounded after decompression: a small gzip body cannot inflate into gigabytes.

httpx inflates a ``Content-Encoding: gzip`` (or ``deflate``) body one network read at a time,
and one 64 KiB read of a gzip bomb inflates to ~64 MiB before anyone counts it.
:func:`bound_reply` gives a response a decoder of our own instead: it inflates with zlib's
``max_length``, so no more than the limit is ever produced, and counts every decoded byte of the
body, streamed or read whole. Past the limit it raises :class:`ReplyTooLargeError` naming the
server, the operation and the limit (the client's ``max_reply_bytes``). An encoding it does not
know how to bound (``br``, ``zstd``, anything else) is refused rather than passed on undecoded;
requests say ``Accept-Encoding: gzip, deflate`` so a conforming server never sends one.
"""

from __future__ import annotations

import zlib
from collections.abc import Iterator
from typing import Any

import httpx

from ..errors import ConfigError, ProtocolError

__all__ = ["ACCEPT_ENCODING", "DEFAULT_MAX_REPLY_BYTES", "BoundedDecoder", "ReplyBudget", "ReplyTooLargeError",
           "bound_reply", "bounded_decoder", "check_max_reply_bytes"]

#: The default ``max_reply_bytes`` of a model client: 64 MiB of decoded reply (a long answer is ~100 KB).
DEFAULT_MAX_REPLY_BYTES = 64 * 1024 * 1024
#: The encodings :func:`bound_reply` can bound, as sent in every request.
ACCEPT_ENCODING = "gzip, deflate"


class ReplyTooLargeError(ProtocolError):
    """A server's reply (after decompression) is larger than the client's ``max_reply_bytes``."""


def check_max_reply_bytes(owner: str, value: Any) -> int:
    """``value`` as a positive int of bytes (not a bool), else :class:`~agents_core.errors.ConfigError`."""
    if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
        raise ConfigError(f"{owner}: max_reply_bytes must be a positive int, got {value!r}")
    return value


class ReplyBudget:
    """Counts the decoded bytes of one reply (or one stream) against ``limit``.

    :param limit: the most bytes allowed.
    :param label: names the client, its server and the operation in the error.
    """

    def __init__(self, limit: int, label: str) -> None:
        self.limit = limit
        self.label = label
        self.used = 0

    def left(self) -> int:
        """Bytes that may still come."""
        return self.limit - self.used

    def add(self, n: int) -> None:
        """Count ``n`` more bytes; raise :class:`ReplyTooLargeError` past the limit."""
        self.used += n
        if self.used > self.limit:
            raise self.error()

    def error(self) -> ReplyTooLargeError:
        """The error naming the server, the operation and the limit."""
        return ReplyTooLargeError(f"{self.label}: the reply is larger than max_reply_bytes={self.limit} "
                                  "(counted after decompression); refused")


class _Inflater:
    """One ``gzip`` / ``deflate`` layer, inflating no more than its budget allows."""

    def __init__(self, encoding: str) -> None:
        self.encoding = encoding
        self._raw_deflate = False
        self._obj = zlib.decompressobj(16 + zlib.MAX_WBITS if encoding == "gzip" else zlib.MAX_WBITS)
        self._first = True

    def decode(self, data: bytes, budget: ReplyBudget) -> bytes:
        if self._first and self.encoding == "deflate" and data:
            self._first = False
            # Some servers send raw deflate (no zlib header) as "deflate", as httpx also accepts.
            try:
                probe = zlib.decompressobj(zlib.MAX_WBITS)
                probe.decompress(data[:2])
            except zlib.error:
                self._obj = zlib.decompressobj(-zlib.MAX_WBITS)
        try:
            out = self._obj.decompress(data, budget.left() + 1)
        except zlib.error as exc:
            raise ProtocolError(f"{budget.label}: the reply's {self.encoding} body is damaged: {exc}") from exc
        if self._obj.unconsumed_tail or len(out) > budget.left():
            raise budget.error()
        return out

    def flush(self, budget: ReplyBudget) -> bytes:
        try:
            out = self._obj.flush(budget.left() + 1)
        except zlib.error as exc:
            raise ProtocolError(f"{budget.label}: the reply's {self.encoding} body is damaged: {exc}") from exc
        if len(out) > budget.left():
            raise budget.error()
        return out


class BoundedDecoder:
    """Inflate each layer within the budget, count the result."""

    def __init__(self, encodings: list[str], budget: ReplyBudget) -> None:
        # Content-Encoding lists the layers in the order they were applied: undo them last first.
        self._layers = [_Inflater(e) for e in reversed(encodings)]
        self._budget = budget

    def decode(self, data: bytes) -> bytes:
        for layer in self._layers:
            data = layer.decode(data, self._budget)
        self._budget.add(len(data))
        return data

    def flush(self) -> bytes:
        data = b""
        for layer in self._layers:  # what one layer still held goes through the next ones too
            data = (layer.decode(data, self._budget) if data else b"") + layer.flush(self._budget)
        self._budget.add(len(data))
        return data


class _BoundedStream(httpx.SyncByteStream):
    """A response body stream giving the decoded bytes of ``stream`` through ``decoder``."""

    def __init__(self, stream: Any, decoder: BoundedDecoder) -> None:
        self._stream = stream
        self._decoder = decoder

    def __iter__(self) -> Iterator[bytes]:
        for raw in self._stream:
            out = self._decoder.decode(raw)
            if out:
                yield out
        tail = self._decoder.flush()
        if tail:
            yield tail

    def close(self) -> None:
        self._stream.close()


def bounded_decoder(headers: Any, budget: ReplyBudget) -> BoundedDecoder:
    """The decoder of a reply with these (httpx or httpx2) ``headers``, bounded by ``budget``.

    Strips ``Content-Encoding`` and ``Content-Length`` from ``headers`` (the decoder inflates, so
    the HTTP client must see an identity body). Raises :class:`ReplyTooLargeError` at once when
    ``Content-Length`` already says too much, and :class:`~agents_core.errors.ProtocolError` for an
    encoding that cannot be bounded.
    """
    encodings = [v.strip().lower() for v in headers.get_list("content-encoding", split_commas=True)]
    encodings = [e for e in encodings if e and e != "identity"]
    unknown = sorted({e for e in encodings if e not in ("gzip", "deflate")})
    if unknown:
        raise ProtocolError(f"{budget.label}: the reply is encoded as {', '.join(unknown)}, which this client "
                            f"did not ask for (it accepts {ACCEPT_ENCODING}); refused")
    length = headers.get("content-length", "")
    if not encodings and length.isdigit() and int(length) > budget.left():
        raise budget.error()
    for name in ("content-encoding", "content-length"):
        if name in headers:
            del headers[name]
    return BoundedDecoder(encodings, budget)


def bound_reply(response: httpx.Response, budget: ReplyBudget) -> None:
    """Give ``response`` (body not read yet) a decoder that stops at ``budget``'s limit.

    Raises as :func:`bounded_decoder` does.
    """
    response.stream = _BoundedStream(response.stream, bounded_decoder(response.headers, budget))
