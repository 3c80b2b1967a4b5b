"""Images as binary WebSocket frames: a 24-byte header, then the image's bytes.

A client that opens ``WS /api/outputs?frames=binary`` gets every image (Image, CompressedImage in
JPEG or PNG) as one binary frame instead of a JSON ``image`` frame with base64 data: a third smaller
on the wire, no base64 or JSON on either side, and the browser decodes it straight from the buffer
(``createImageBitmap``). Everything else stays a JSON text frame.

The header, little-endian (:data:`HEADER`, ``struct`` format ``<BBHIIIq``):

======  ======  ==============================================================================
offset  type    field
======  ======  ==============================================================================
0       u8      ``version`` (:data:`VERSION`, 1)
1       u8      ``encoding``: 1 JPEG, 2 PNG, 3 raw rgb8 (``width * height * 3`` bytes, rows top-down)
2       u16     ``topic_id``: the output's ``id`` in ``GET /api/interfaces``
4       u32     ``width`` of the image (0: not known, a compressed image)
8       u32     ``height`` (0: not known)
12      u32     ``size``: how many payload bytes follow the header (the frame is 24 + size bytes)
16      i64     ``stamp_ns``: the value's header stamp, -1 when it has none
======  ======  ==============================================================================

``width`` / ``height`` are the image's own size even when the payload was downscaled (a side past
JPEG's limit), so boxes in image pixels still line up when it is drawn at that size.
"""

from __future__ import annotations

import struct
from typing import NamedTuple

from .frames import RGB8_MIME

__all__ = ["ENCODINGS", "HEADER", "VERSION", "BinaryFrame", "pack_image", "unpack"]

#: The header's layout (see the module docstring).
HEADER = struct.Struct("<BBHIIIq")
VERSION = 1
#: mime -> the header's ``encoding``; an image of another mime is sent as a JSON frame.
ENCODINGS = {"image/jpeg": 1, "image/png": 2, RGB8_MIME: 3}
_MAX_TOPIC_ID = 0xFFFF
_MAX_U32 = 0xFFFF_FFFF


class BinaryFrame(NamedTuple):
    """A parsed binary frame (for Python clients and the tests; the page parses it in JavaScript)."""

    version: int
    encoding: int
    topic_id: int
    width: int
    height: int
    stamp_ns: int | None
    payload: bytes


def pack_image(topic_id: int, mime: str, data: bytes, width: int | None, height: int | None,
               stamp_ns: int | None) -> bytes | None:
    """The binary frame of an image, or None when it has none (an unknown mime, a field out of range)."""
    encoding = ENCODINGS.get(mime)
    if (encoding is None or not 0 <= topic_id <= _MAX_TOPIC_ID or len(data) > _MAX_U32
            or not 0 <= (width or 0) <= _MAX_U32 or not 0 <= (height or 0) <= _MAX_U32):
        return None
    stamp = stamp_ns if stamp_ns is not None and 0 <= stamp_ns < 2**63 else -1
    return HEADER.pack(VERSION, encoding, topic_id, width or 0, height or 0, len(data), stamp) + data


def unpack(frame: bytes) -> BinaryFrame:
    """Parse a binary frame; ValueError when it is not one (short, another version, a size that disagrees)."""
    if len(frame) < HEADER.size:
        raise ValueError(f"a binary frame has at least {HEADER.size} bytes, got {len(frame)}")
    version, encoding, topic_id, width, height, size, stamp = HEADER.unpack_from(frame)
    if version != VERSION:
        raise ValueError(f"binary frame version {version}, expected {VERSION}")
    if encoding not in ENCODINGS.values():
        raise ValueError(f"unknown encoding {encoding}")
    if size != len(frame) - HEADER.size:
        raise ValueError(f"the header says {size} payload bytes, the frame has {len(frame) - HEADER.size}")
    return BinaryFrame(version, encoding, topic_id, width, height, None if stamp < 0 else stamp,
                       bytes(frame[HEADER.size:]))
