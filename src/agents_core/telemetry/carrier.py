"""The W3C trace context in a Zenoh sample's attachment, written and read without a msgpack call.

A sample's attachment is the msgpack map ``{"seq": n, "stamp_ns": t}`` (:mod:`agents_zenoh.pubsub`).
With telemetry on, a third entry ``"traceparent": "00-<trace id>-<span id>-<flags>"`` (the W3C
header, 55 ASCII characters) follows, so any msgpack reader still decodes the attachment; readers
that know only the first two keys ignore it. :func:`traceparent_of` finds it with one search,
bounded by the attachment's size, and accepts only a well-formed header.
"""

from __future__ import annotations

import re

__all__ = ["MAX_ATTACHMENT", "TRACEPARENT_KEY", "append_traceparent", "traceparent_of"]

#: The key of the entry, as msgpack writes a 11-byte str (fixstr 0xab).
TRACEPARENT_KEY = b"\xabtraceparent"
#: Attachments longer than this are not searched (ours are 29 bytes, 97 with the context).
MAX_ATTACHMENT = 512
_HEADER = re.compile(rb"00-[0-9a-f]{32}-[0-9a-f]{16}-[0-9a-f]{2}\Z")


def append_traceparent(attachment: bytes, traceparent: str) -> bytes:
    """``attachment`` (a msgpack fixmap of up to 14 entries) with the ``traceparent`` entry added."""
    value = traceparent.encode("ascii")
    return bytes([attachment[0] + 1]) + attachment[1:] + TRACEPARENT_KEY + bytes([0xD9, len(value)]) + value


def traceparent_of(attachment: bytes | None) -> str | None:
    """The ``traceparent`` entry of an attachment, None when absent or malformed."""
    if not attachment or len(attachment) > MAX_ATTACHMENT:
        return None
    at = attachment.find(TRACEPARENT_KEY)
    if at < 0:
        return None
    start = at + len(TRACEPARENT_KEY)
    if attachment[start:start + 1] != b"\xd9":
        return None
    length = attachment[start + 1] if len(attachment) > start + 1 else 0
    value = attachment[start + 2:start + 2 + length]
    return value.decode("ascii") if _HEADER.match(value) else None
