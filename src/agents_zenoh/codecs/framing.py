"""Framing: how a msgpack document and its numpy arrays make one Zenoh payload (:func:`pack`, :func:`unpack`).

A sample's payload is a *msgpack stream*: one msgpack object, the **document** (the type's
schema, listed by :func:`~agents_zenoh.codecs.describe_schemas` and in ``docs/zenoh-wire-format.md``), optionally
followed by msgpack ``bin`` objects that hold the raw bytes of the document's numpy arrays,
each preceded by zero or more msgpack ``nil`` bytes (``0xc0``) that pad its data to an 8-byte
boundary. In the document an array is a map::

    {"__ndarray__": 0, "dtype": "|u1", "shape": [480, 640, 3]}

where ``__ndarray__`` is the index of the trailing ``bin`` object that holds the bytes (C order)
or, from a third-party publisher that prefers a single document, the ``bin`` itself.

Why a trailing ``bin`` rather than the bytes inside the document: unpacking a ``bin`` copies
it, while an array read straight from the payload buffer (``np.frombuffer``) is not copied at
all. For a 640x480x3 image the framing measured (medians, this 2-core machine) 24 µs encode /
3 µs decode, against 43 µs / 24 µs with the array inside the document (msgpack-numpy style);
the whole Image codec, message object included, 28 µs / 11 µs against 42 µs / 27 µs.
Decoded arrays are therefore read-only views of the received payload.

This module is the framing only; the codecs that turn values into documents are in
:mod:`agents_zenoh.codecs.derivation` and :mod:`agents_zenoh.codecs.registry`, and what decoding
may cost in :mod:`agents_zenoh.codecs.limits`.
"""

from __future__ import annotations

import math
import re
from typing import Any

import msgpack  # type: ignore[import-untyped]  # msgpack ships no type information
import numpy as np
import numpy.typing as npt

from .errors import CodecError
from .limits import DEFAULT_DECODE_LIMITS, MAX_DIM, MAX_NDIM, DecodeLimits, counting_hooks

__all__ = ["MSGPACK", "NDARRAY_KEY", "REUSE_ABOVE", "pack", "unpack"]

#: The Zenoh encoding of every payload this adapter writes; the type name is its schema.
MSGPACK = "application/msgpack"

#: The key that marks a map of the document as a numpy array.
NDARRAY_KEY = "__ndarray__"
_NDARRAY_BYTES = NDARRAY_KEY.encode()
# Simple numeric dtypes only ("<f4", "|u1", ">i8", ...): a dtype string from the wire must never
# describe a structured or object dtype.
_DTYPE_RE = re.compile(r"^[<>|=][biufc][1-9][0-9]?$")
_ALIGN = 8
_NIL, _BIN8, _BIN16, _BIN32 = 0xC0, 0xC4, 0xC5, 0xC6
# The document of one sample is small (arrays travel after it); this much is fed to the
# unpacker first to find where it ends, so a large payload is never copied just for that.
_FIRST_FEED = 4096
#: Payloads at least this large are written into a publisher's reusable buffer (see :func:`pack`).
REUSE_ABOVE = 64 * 1024


def pack(document: Any, into: bytearray | None = None) -> bytes | bytearray:
    """Encode ``document`` as a payload: msgpack, with numpy arrays as trailing ``bin`` objects.

    With ``into``, a payload of :data:`REUSE_ABOVE` bytes or more is written into that buffer
    (resized to fit), which is returned: building a fresh multi-megabyte ``bytes`` per sample
    costs page faults (about 0.9 ms for a 640x480x3 image here, against 40 µs when a buffer is
    reused), and Zenoh copies the payload on ``put`` anyway, so the buffer is free again after.
    """
    if type(document) in _PLAIN_SCALARS:
        # A String, a number: no array can be in it, so no hook and no copy (the same bytes).
        try:
            return msgpack.packb(document, use_bin_type=True)  # type: ignore[no-any-return]
        except (TypeError, ValueError, OverflowError) as exc:
            raise CodecError(str(exc)) from exc
    arrays: list[npt.NDArray[Any]] = []

    def default(obj: Any) -> Any:
        if isinstance(obj, np.ndarray):
            arr = _wire_array(obj)
            arrays.append(arr)
            return {NDARRAY_KEY: len(arrays) - 1, "dtype": arr.dtype.str, "shape": list(arr.shape)}
        if isinstance(obj, np.generic):
            return obj.item()
        if isinstance(obj, bytearray | memoryview):
            return bytes(obj)
        raise TypeError(f"cannot encode a {type(obj).__name__} in msgpack")

    try:
        head = msgpack.packb(document, default=default, use_bin_type=True)
    except (TypeError, ValueError, OverflowError) as exc:
        raise CodecError(str(exc)) from exc
    if not arrays:
        return bytes(head)
    if len(arrays) == 1:
        received = _received_payload(head, arrays[0])
        if received is not None:
            return received
    chunks: list[bytes | memoryview] = [head]
    pos = len(head)
    for arr in arrays:
        nbytes = arr.nbytes
        if nbytes >= 2**32:
            raise CodecError(f"an array of {nbytes} bytes does not fit in one msgpack bin")
        pad = -(pos + 5) % _ALIGN
        chunks.append(b"\xc0" * pad + b"\xc6" + nbytes.to_bytes(4, "big"))
        chunks.append(arr.reshape(-1).view(np.uint8).data)
        pos += pad + 5 + nbytes
    if into is None or pos < REUSE_ABOVE:
        return b"".join(chunks)
    if len(into) > pos:
        del into[pos:]
    elif len(into) < pos:
        into.extend(bytes(pos - len(into)))
    with memoryview(into) as view:
        offset = 0
        for chunk in chunks:
            view[offset:offset + len(chunk)] = chunk
            offset += len(chunk)
    return into


def _received_payload(head: bytes, arr: npt.NDArray[Any]) -> bytes | None:
    """The received payload that this document and array would be written as again, else None.

    A decoded array is a read-only view of the payload it came in (see :func:`unpack`). When a
    component publishes such a value unchanged (a relay, a filter that passes frames on), the
    payload it would write is that one, byte for byte: it is returned as it is, and the pixels are
    not copied into a new buffer (~0.9 MB for a 640x480 image). Checked, not assumed: the array
    must cover the payload's one trailing ``bin`` exactly, and the document and padding before it
    must be the bytes :func:`pack` writes.
    """
    base: Any = arr
    while isinstance(base, np.ndarray):
        base = base.base
    source = base.obj if isinstance(base, memoryview) else None
    if type(source) is not bytes:
        return None
    nbytes = arr.nbytes
    pad = -(len(head) + 5) % _ALIGN
    start = len(head) + pad + 5
    if len(source) != start + nbytes or not nbytes:
        return None
    if arr.__array_interface__["data"][0] - np.frombuffer(source, np.uint8).__array_interface__["data"][0] != start:
        return None
    prefix = head + b"\xc0" * pad + b"\xc6" + nbytes.to_bytes(4, "big")
    return source if source.startswith(prefix) else None


def _wire_array(obj: npt.NDArray[Any]) -> npt.NDArray[Any]:
    if obj.dtype.kind not in "biufc" or obj.dtype.fields is not None:
        raise TypeError(f"numpy arrays of dtype {obj.dtype} cannot be sent (numeric dtypes only)")
    if obj.dtype.byteorder == ">":
        obj = obj.astype(obj.dtype.newbyteorder("<"))
    # Not np.ascontiguousarray: it turns a 0-d array into a 1-d one.
    return obj if obj.flags.c_contiguous else obj.copy(order="C")


def unpack(payload: bytes | bytearray | memoryview, limits: DecodeLimits | None = None) -> Any:
    """Decode a payload written by :func:`pack` (or by any client following the wire format).

    Arrays whose bytes follow the document are views of ``payload`` (no copy, read-only).
    ``limits`` bound what the document may cost (default :data:`DEFAULT_DECODE_LIMITS`;
    :func:`decode_value` passes the type's own). Raises :class:`CodecError` naming what is wrong.
    """
    limits = DEFAULT_DECODE_LIMITS if limits is None else limits
    if type(payload) is bytes and 0 < len(payload) < limits._uncounted_below and payload[0] in _SCALAR_HEADS:
        # A small scalar document (a String, a number: what most topics carry): one C call,
        # no object hook needed. Anything else it meets (trailing arrays, a limit, bad bytes)
        # goes down the full path, which decides and names what is wrong.
        try:
            return msgpack.unpackb(payload, **limits._options)
        except Exception:
            pass
    elif type(payload) is bytes and 0 < len(payload) < limits._uncounted_below and _NDARRAY_BYTES not in payload:
        # A small map or list without an array in it (no "__ndarray__" anywhere in its bytes, so no map
        # for the hook to resolve): one C call without the Python object hook per map (goal replies,
        # requests). Anything it does not read alone (trailing arrays, a limit) takes the full path.
        try:
            return msgpack.unpackb(payload, **limits._options)
        except Exception:
            pass
    buf = memoryview(payload).cast("B")
    if not buf:
        raise CodecError("the payload is empty")
    bins: list[tuple[int, int]] = []
    bad: list[tuple[_BadArray, str]] = []

    def resolve(obj: dict[Any, Any]) -> Any:
        if NDARRAY_KEY not in obj:
            return obj
        try:
            return _array_from(obj, buf, bins)
        except CodecError as exc:
            # The map does not know where it sits in the document; keep decoding (bounded by the
            # budget) and name the field once the whole document is there.
            marker = _BadArray()
            bad.append((marker, str(exc)))
            return marker

    try:
        document: Any = _NO_DOCUMENT
        if len(buf) < limits._uncounted_below:
            # A small payload is most often a document alone (no arrays after it): one C call,
            # bounded by the type's length limits, without first walking the document to its end.
            try:
                document = msgpack.unpackb(buf, object_hook=resolve, **limits._options)
            except Exception:
                # Trailing arrays, or a payload that is bad anyway: the framed path decides, and
                # names what is wrong precisely.
                document = _NO_DOCUMENT
                bad.clear()
        if document is _NO_DOCUMENT:
            end = _document_end(buf, limits.max_document_bytes)
            bins.extend(_trailing_bins(buf, end))
            if end < limits._uncounted_below:
                document = msgpack.unpackb(buf[:end], object_hook=resolve, **limits._options)
            else:
                document = msgpack.unpackb(buf[:end], **counting_hooks(limits, end, resolve), **limits._options)
    except CodecError:
        raise
    except ValueError as exc:
        if "exceeds max_" in str(exc):
            # msgpack's words name the DecodeLimits field: "5000 exceeds max_array_len(32)".
            raise CodecError(f"the document exceeds a decode limit of this type ({exc}; see DecodeLimits)") from exc
        raise CodecError(f"invalid msgpack ({_describe(exc)})") from exc
    except Exception as exc:
        raise CodecError(f"invalid msgpack ({_describe(exc)})") from exc
    if bad:
        marker, reason = bad[0]
        where = _path_to(document, marker)
        raise CodecError(f"field {where!r}: {reason}" if where else reason)
    return document


_NO_DOCUMENT: Any = object()

#: Documents :func:`pack` writes with one msgpack call (exact types: numpy scalars take the full path).
_PLAIN_SCALARS = frozenset((str, int, float, bool, bytes, type(None)))

#: msgpack's first bytes of a scalar: positive and negative fixint, nil, false, true, bin 8/16/32,
#: float 32/64, (u)int 8-64, fixstr and str 8/16/32 (no map, array or ext).
_SCALAR_HEADS = frozenset((*range(0x00, 0x80), *range(0xE0, 0x100), 0xC0, 0xC2, 0xC3, 0xC4, 0xC5, 0xC6,
                           *range(0xCA, 0xD4), *range(0xA0, 0xC0), 0xD9, 0xDA, 0xDB))


class _BadArray:
    """Stands in for an array map that cannot be decoded, until its place in the document is known."""

    __slots__ = ()


def _path_to(document: Any, target: object) -> str:
    """Where ``target`` sits in ``document``, as ``image.data`` / ``frames[2].data`` ('' at the root)."""
    stack: list[tuple[Any, str]] = [(document, "")]
    while stack:
        node, path = stack.pop()
        if node is target:
            return path
        if isinstance(node, dict):
            for key, value in node.items():
                stack.append((value, f"{path}.{key}" if path else str(key)))
                stack.append((key, f"{path}.<key>" if path else "<key>"))
        elif isinstance(node, list):
            stack.extend((value, f"{path}[{i}]") for i, value in enumerate(node))
    return ""


def _document_end(buf: memoryview, limit: int) -> int:
    # Skipping walks the msgpack headers without building objects (~3 ms per MB), and never past
    # the type's document limit, so an oversized document is refused before it is unpacked.
    cap = min(len(buf), limit)
    unpacker = msgpack.Unpacker(raw=False, strict_map_key=False, max_buffer_size=cap)
    fed = min(cap, _FIRST_FEED)
    unpacker.feed(buf[:fed])
    while True:
        try:
            unpacker.skip()
        except msgpack.OutOfData:
            if fed == cap:
                if cap < len(buf):
                    raise CodecError(f"the msgpack document is larger than {limit} bytes "
                                     "(DecodeLimits.max_document_bytes for this type)") from None
                raise CodecError(f"the payload ({len(buf)} bytes) ends inside its msgpack document") from None
            unpacker.feed(buf[fed:cap])
            fed = cap
        except Exception as exc:
            raise CodecError(f"invalid msgpack ({_describe(exc)})") from exc
        else:
            return int(unpacker.tell())


def _describe(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__


def _trailing_bins(buf: memoryview, pos: int) -> list[tuple[int, int]]:
    """(offset, length) of each ``bin`` after the document, skipping ``nil`` padding."""
    bins: list[tuple[int, int]] = []
    total = len(buf)
    while pos < total:
        marker = buf[pos]
        if marker == _NIL:
            pos += 1
            continue
        width = {_BIN8: 1, _BIN16: 2, _BIN32: 4}.get(marker)
        if width is None:
            raise CodecError(f"unexpected byte 0x{marker:02x} at offset {pos} after the document "
                             "(only msgpack bin objects and nil padding may follow it)")
        start = pos + 1 + width
        if start > total:
            raise CodecError(f"the payload ends inside a bin header at offset {pos}")
        length = int.from_bytes(buf[pos + 1:start], "big")
        if start + length > total:
            raise CodecError(f"bin at offset {pos} claims {length} bytes; only {total - start} follow")
        bins.append((start, length))
        pos = start + length
    return bins


def _array_from(desc: dict[Any, Any], buf: memoryview, bins: list[tuple[int, int]]) -> npt.NDArray[Any]:
    dtype_str, shape, ref = desc.get("dtype"), desc.get("shape"), desc[NDARRAY_KEY]
    if not isinstance(dtype_str, str) or not _DTYPE_RE.match(dtype_str):
        raise CodecError(f"array dtype {dtype_str!r} is not a numeric dtype string such as '<f4' or '|u1'")
    if isinstance(shape, list) and len(shape) > MAX_NDIM:
        raise CodecError(f"array shape has {len(shape)} dimensions; at most {MAX_NDIM} are accepted")
    if not isinstance(shape, list) or not all(isinstance(d, int) and not isinstance(d, bool) and d >= 0
                                              for d in shape):
        raise CodecError(f"array shape {shape!r} is not a list of non-negative ints")
    try:
        dtype = np.dtype(dtype_str)
    except TypeError as exc:
        raise CodecError(f"array dtype {dtype_str!r}: {exc}") from exc
    # Even an empty array (a zero elsewhere in its shape) may not claim absurd dimensions: code
    # downstream sizes buffers, image steps and loops from the shape, and numpy refuses shapes
    # whose non-zero dimensions multiply past its address space. Python ints: the products are
    # exact, never wrapped around to a small number.
    count = math.prod(shape)
    if (shape and max(shape) > MAX_DIM) or (not count and math.prod(d for d in shape if d) * dtype.itemsize >= 2**63):
        raise CodecError(f"array shape {shape} claims absurd dimensions (each must be at most {MAX_DIM}, "
                         "and their product in bytes below 2**63)")
    if isinstance(ref, bytes):
        data, offset, length = memoryview(ref), 0, len(ref)
    elif isinstance(ref, int) and not isinstance(ref, bool) and 0 <= ref < len(bins):
        data, (offset, length) = buf, bins[ref]
    else:
        raise CodecError(f"array refers to bin {ref!r}, but {len(bins)} bin(s) follow the document")
    if length != count * dtype.itemsize:
        raise CodecError(f"array of shape {shape} and dtype {dtype_str} needs {count * dtype.itemsize} "
                         f"bytes, its bin has {length}")
    if count == 0:
        return np.empty(tuple(shape), dtype)
    return np.frombuffer(data, dtype=dtype, count=count, offset=offset).reshape(tuple(shape))

