"""Msgpack codecs: the Zenoh wire form of every registered message type.

A sample's payload is a *msgpack stream*: one msgpack object, the **document** (the type's
schema, listed by :func:`describe_schemas` and in ``docs/zenoh-wire-format.md``), optionally
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

:func:`register_codec` adds a codec for a user-registered message type; a codec's ``encode``
returns a msgpack-able document (numpy arrays anywhere in it travel as above) and its
``decode`` turns such a document back into the value.

Decoding is bounded (see :class:`DecodeLimits`): any peer may send anything, and a few megabytes
of msgpack can expand ~70x into small Python objects (an empty map is one byte on the wire, a
64-byte dict in memory). Each type's codec carries limits fitted to what the type can hold; the
document is measured and unpacked under them, and a payload that exceeds one is rejected with a
:class:`CodecError` before it costs more than a fixed multiple of its size.
"""

from __future__ import annotations

import math
import re
import threading
from collections.abc import Callable, Mapping
from typing import Any

import attrs
import msgpack  # type: ignore[import-untyped]  # msgpack ships no type information
import numpy as np
import numpy.typing as npt
from attrs import define, field

from agents_core import messages as m
from agents_core.errors import TypeValidationError
from agents_core.supported_types import SupportedType, get_type, registered_types

__all__ = [
    "DEFAULT_DECODE_LIMITS",
    "MSGPACK",
    "Codec",
    "CodecError",
    "DecodeLimits",
    "codec_for",
    "decode_limits",
    "decode_value",
    "describe_schemas",
    "encode_value",
    "pack",
    "register_codec",
    "set_decode_limits",
    "unpack",
]

#: The Zenoh encoding of every payload this adapter writes; the type name is its schema.
MSGPACK = "application/msgpack"

_NDARRAY_KEY = "__ndarray__"
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


class CodecError(TypeValidationError):
    """A value cannot be encoded as, or a payload decoded into, its message type.

    Also raised when a publisher or subscription is created for a type that has no codec.
    """


# -- decoding limits ----------------------------------------------------------------------------

_KIB, _MIB = 1024, 1024 * 1024
# Numpy refuses more than 64 dimensions; no message needs more than a handful.
_MAX_NDIM = 32
# One dimension of a received array: ROS 2 sizes are uint32, and no real array in one sample is longer.
_MAX_DIM = 2**32 - 1
# The memory of decoded containers, estimated as msgpack builds them (sys.getsizeof costs twice as
# much as the arithmetic): a list is a 56-byte object plus a pointer per item; a map is charged
# 1 KiB plus 48 bytes per entry, because most maps become a message object (a DetectionsMsg with
# its Header and empty arrays measured ~1 KB), so a flood of tiny maps, each a byte on the wire,
# is charged for what the codec will build from it, not just for the dict.
_LIST_BASE, _LIST_ITEM = 56, 8
_MAP_BASE, _MAP_ITEM = 1 * _KIB, 48
# The most one byte of a document can be charged: a map (one byte opens it, two more per entry).
_WORST_PER_BYTE = _MAP_BASE + _MAP_ITEM
# Every document may use this much beyond max_expansion x its size: small documents (a Header map
# alone is 184 bytes from ~30 on the wire) are never refused for their fixed costs.
_BUDGET_SLACK = 256 * _KIB


def _refuse_ext(code: int, data: bytes) -> Any:
    raise CodecError(f"msgpack ext type {code} is not part of the wire format")


def _positive(instance: Any, attribute: attrs.Attribute[int], value: int) -> None:
    minimum = 1 if attribute.name in ("max_document_bytes", "max_expansion") else 0
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise CodecError(f"DecodeLimits.{attribute.name} must be an int >= {minimum}, got {value!r}")


@define(frozen=True)
class DecodeLimits:
    """How much a received payload may cost to decode; exceeding any limit rejects it with :class:`CodecError`.

    The limits apply to the msgpack **document** (everything before the trailing array ``bin``
    objects, which are never copied and so cost nothing to accept):

    - ``max_document_bytes``: the document's size; checked before anything is unpacked.
    - ``max_str_len``, ``max_bin_len``, ``max_array_len``, ``max_map_len``: the length of any one
      str, bin (an array's bytes inline in the document), array or map, checked by msgpack as it
      reads each header, before it allocates (``max_*_len`` of :class:`msgpack.Unpacker`).
    - ``max_arrays``, ``max_maps``: how many arrays and maps the whole document may hold (each
      map usually becomes a message object, the costly part of decoding, in time as in memory).
    - ``max_expansion``: the memory of the decoded maps and arrays, estimated as they are built
      (each map charged 1 KiB for the message it usually becomes), may not exceed
      ``max_expansion`` x the document's size + 256 KiB.

    Together they keep the memory a payload can cost within a fixed multiple of its size (and
    within an absolute bound per type), keep the time bounded too, and make an oversized
    payload fail at its first offending header. The built-in types have limits fitted to their
    schemas (see ``docs/zenoh-wire-format.md``); raise one with :func:`set_decode_limits` where
    a topic legitimately carries more. A limit of 0 on a length forbids all but empty ones.
    """

    max_document_bytes: int = field(default=64 * _MIB, validator=_positive)
    max_str_len: int = field(default=64 * _MIB, validator=_positive)
    max_bin_len: int = field(default=64 * _MIB, validator=_positive)
    max_array_len: int = field(default=262_144, validator=_positive)
    max_map_len: int = field(default=4096, validator=_positive)
    max_arrays: int = field(default=262_144, validator=_positive)
    max_maps: int = field(default=65_536, validator=_positive)
    max_expansion: int = field(default=32, validator=_positive)
    # Computed once (a sample's decode takes a few µs): msgpack's options for these limits, and the
    # document size below which no count or budget can be exceeded, so nothing needs counting.
    _options: dict[str, Any] = field(init=False, repr=False, eq=False)
    _uncounted_below: int = field(init=False, repr=False, eq=False)

    def __attrs_post_init__(self) -> None:
        cap = self.max_document_bytes
        options = {"max_str_len": min(self.max_str_len, cap), "max_bin_len": min(self.max_bin_len, cap),
                   "max_array_len": min(self.max_array_len, cap), "max_map_len": min(self.max_map_len, cap),
                   # Nothing in the wire format is a msgpack ext (timestamps included): refuse them all.
                   "max_ext_len": 0, "ext_hook": _refuse_ext, "raw": False, "strict_map_key": False}
        if self.max_array_len == self.max_map_len == 0 and min(self.max_arrays, self.max_maps) >= 1:
            below = cap + 1  # nothing can nest: the document is at most one empty container
        else:
            # Even if every byte opened a map, a document this small stays within every limit.
            below = min(self.max_maps, self.max_arrays,
                        _BUDGET_SLACK // max(1, _WORST_PER_BYTE - self.max_expansion)) + 1
        object.__setattr__(self, "_options", options)
        object.__setattr__(self, "_uncounted_below", below)


#: The limits of a codec registered without its own (:func:`register_codec`) and of :func:`unpack`
#: called without ``limits`` (service requests and replies).
DEFAULT_DECODE_LIMITS = DecodeLimits()

# The built-in types, by what their documents hold (see _builtin_codecs):
# a bool / int / float: no containers at all.
_SCALAR_LIMITS = DecodeLimits(max_document_bytes=1 * _KIB, max_str_len=1 * _KIB, max_bin_len=1 * _KIB,
                              max_array_len=0, max_map_len=0, max_arrays=1, max_maps=1)
# String: one str (long LLM outputs included, up to 16 MiB); no containers.
_TEXT_LIMITS = DecodeLimits(max_document_bytes=16 * _MIB, max_str_len=16 * _MIB, max_bin_len=1 * _KIB,
                            max_array_len=0, max_map_len=0, max_arrays=1, max_maps=1)
# Fixed-shape messages (Pose, Header, StreamingString, JointState, ...): a few maps, lists of at
# most one value per joint; the only long part is a string (StreamingString.data).
_STRUCT_LIMITS = DecodeLimits(max_document_bytes=16 * _MIB, max_str_len=16 * _MIB, max_bin_len=64 * _KIB,
                              max_array_len=65_536, max_map_len=64, max_arrays=256, max_maps=256)
# One array plus a few scalars (Image, Audio, OccupancyGrid, LaserScan, multi-arrays,
# CompressedImage): a third party may put the array's bytes inside the document, so the document
# may be large, but it holds a handful of small maps and the shape list, nothing more.
_ARRAY_LIMITS = DecodeLimits(max_document_bytes=256 * _MIB, max_str_len=64 * _KIB, max_bin_len=256 * _MIB,
                             max_array_len=_MAX_NDIM, max_map_len=64, max_arrays=256, max_maps=256)
# Perception results (Detections, Trackings, PointsOfInterest): one small list per box / point
# (up to 65,536 of them: a detector's raw candidates are ~10,000), a few maps (the header, an
# optional image). Building 65,536 lists costs ~50 ms, the worst a hostile document can make it.
_PERCEPTION_LIMITS = DecodeLimits(max_document_bytes=256 * _MIB, max_str_len=16 * _MIB, max_bin_len=256 * _MIB,
                                  max_array_len=65_536, max_map_len=64, max_arrays=65_536, max_maps=256)
# Lists of messages: each item is a few maps (a Detections with its header and image, a video
# frame, a trajectory waypoint). Decoding one costs ~10-30 µs, so the item count bounds the time.
_BUNDLE_LIMITS = attrs.evolve(_PERCEPTION_LIMITS, max_maps=4096)  # ~1000 sources / frames
# Waypoints: one map and four lists each.
_TRAJECTORY_LIMITS = attrs.evolve(_PERCEPTION_LIMITS, max_maps=16_384, max_arrays=4 * 16_384 + 64)


# -- framing: document + trailing array buffers ---------------------------------------------


def pack(document: Any, into: bytearray | None = None) -> bytes | bytearray:
    """Encode ``document`` as a payload: msgpack, with numpy arrays as trailing ``bin`` objects.

    With ``into``, a payload of :data:`REUSE_ABOVE` bytes or more is written into that buffer
    (resized to fit), which is returned: building a fresh multi-megabyte ``bytes`` per sample
    costs page faults (about 0.9 ms for a 640x480x3 image here, against 40 µs when a buffer is
    reused), and Zenoh copies the payload on ``put`` anyway, so the buffer is free again after.
    """
    arrays: list[npt.NDArray[Any]] = []

    def default(obj: Any) -> Any:
        if isinstance(obj, np.ndarray):
            arr = _wire_array(obj)
            arrays.append(arr)
            return {_NDARRAY_KEY: len(arrays) - 1, "dtype": arr.dtype.str, "shape": list(arr.shape)}
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
    buf = memoryview(payload).cast("B")
    if not buf:
        raise CodecError("the payload is empty")
    end = _document_end(buf, limits.max_document_bytes)
    bins = _trailing_bins(buf, end)
    bad: list[tuple[_BadArray, str]] = []

    def resolve(obj: dict[Any, Any]) -> Any:
        if _NDARRAY_KEY not in obj:
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
        if end < limits._uncounted_below:
            document = msgpack.unpackb(buf[:end], object_hook=resolve, **limits._options)
        else:
            document = msgpack.unpackb(buf[:end], **_counting_hooks(limits, end, resolve), **limits._options)
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


class _BadArray:
    """Stands in for an array map that cannot be decoded, until its place in the document is known."""

    __slots__ = ()


def _counting_hooks(limits: DecodeLimits, size: int, resolve: Callable[[dict[Any, Any]], Any]) -> dict[str, Any]:
    """msgpack hooks that count the maps and arrays of a ``size``-byte document and their memory.

    They run as each container is completed, so a document over budget stops being decoded there.
    """
    maps_left, arrays_left = limits.max_maps, limits.max_arrays
    memory_left = limits.max_expansion * size + _BUDGET_SLACK

    def on_map(obj: dict[Any, Any]) -> Any:
        nonlocal maps_left, memory_left
        maps_left -= 1
        memory_left -= _MAP_BASE + _MAP_ITEM * len(obj)
        if maps_left < 0 or memory_left < 0:
            _over_budget(limits, size, "max_maps" if maps_left < 0 else "max_expansion")
        return resolve(obj)

    def on_list(obj: list[Any]) -> Any:
        nonlocal arrays_left, memory_left
        arrays_left -= 1
        memory_left -= _LIST_BASE + _LIST_ITEM * len(obj)
        if arrays_left < 0 or memory_left < 0:
            _over_budget(limits, size, "max_arrays" if arrays_left < 0 else "max_expansion")
        return obj

    return {"object_hook": on_map, "list_hook": on_list}


def _over_budget(limits: DecodeLimits, size: int, which: str) -> None:
    if which == "max_expansion":
        raise CodecError(f"the {size}-byte document expands to more than {limits.max_expansion}x its size "
                         "in memory (DecodeLimits.max_expansion for this type)")
    kind = "maps" if which == "max_maps" else "arrays"
    raise CodecError(f"the document holds more than {getattr(limits, which)} {kind} "
                     f"(DecodeLimits.{which} for this type)")


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
    dtype_str, shape, ref = desc.get("dtype"), desc.get("shape"), desc[_NDARRAY_KEY]
    if not isinstance(dtype_str, str) or not _DTYPE_RE.match(dtype_str):
        raise CodecError(f"array dtype {dtype_str!r} is not a numeric dtype string such as '<f4' or '|u1'")
    if isinstance(shape, list) and len(shape) > _MAX_NDIM:
        raise CodecError(f"array shape has {len(shape)} dimensions; at most {_MAX_NDIM} are accepted")
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
    if (shape and max(shape) > _MAX_DIM) or (not count and math.prod(d for d in shape if d) * dtype.itemsize >= 2**63):
        raise CodecError(f"array shape {shape} claims absurd dimensions (each must be at most {_MAX_DIM}, "
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


# -- codecs -------------------------------------------------------------------------------------


@define(frozen=True)
class Codec:
    """How one message type travels: value -> document -> value, the schema in words, its decode limits."""

    type_name: str
    encode: Callable[[Any], Any]
    decode: Callable[[Any], Any]
    schema: str = "user-defined"
    limits: DecodeLimits = DEFAULT_DECODE_LIMITS


class _Kind:
    """How one field of a structured type travels (see the ``_struct`` tables below)."""

    def __init__(self, describe: str, encode: Callable[[Any], Any] = lambda v: v,
                 decode: Callable[[Any], Any] = lambda d: d) -> None:
        self.describe = describe
        self.encode = encode
        self.decode = decode


def _scalar(describe: str) -> _Kind:
    return _Kind(describe)


def _vector(describe: str) -> _Kind:
    # Small arrays travel as plain msgpack lists (friendlier to third-party clients than an
    # ndarray descriptor); the message class converts the list back to its numpy dtype.
    return _Kind(describe, encode=lambda arr: arr.tolist())


def _ndarray(describe: str) -> _Kind:
    def decode(doc: Any) -> Any:
        if not isinstance(doc, np.ndarray):
            raise CodecError(f"expected an ndarray map ({_NDARRAY_KEY}, dtype, shape), got {type(doc).__name__}")
        return doc

    return _Kind(f"ndarray {describe}", decode=decode)


def _nested(codec: Codec) -> _Kind:
    return _Kind(codec.type_name, encode=codec.encode, decode=codec.decode)


def _optional(kind: _Kind) -> _Kind:
    return _Kind(f"{kind.describe} | nil", encode=lambda v: None if v is None else kind.encode(v),
                 decode=lambda d: None if d is None else kind.decode(d))


def _list_of(kind: _Kind) -> _Kind:
    def decode(doc: Any) -> Any:
        if not isinstance(doc, list):
            raise CodecError(f"expected a list, got {type(doc).__name__}")
        out = []
        for i, item in enumerate(doc):
            try:
                out.append(kind.decode(item))
            except Exception as exc:
                raise CodecError(f"[{i}]: {exc}") from exc
        return out

    return _Kind(f"[{kind.describe}, ...]", encode=lambda v: [kind.encode(x) for x in v], decode=decode)


def _tagged(options: Mapping[str, Codec]) -> _Kind:
    """One of several structured types, told apart by an added ``"type"`` key."""
    by_class = {_value_class(name): (name, codec) for name, codec in options.items()}

    def encode(value: Any) -> Any:
        name, codec = by_class[type(value)]
        return {"type": name, **codec.encode(value)}

    def decode(doc: Any) -> Any:
        if not isinstance(doc, dict) or doc.get("type") not in options:
            raise CodecError(f"expected a map with 'type' one of {sorted(options)}")
        return options[doc["type"]].decode({k: v for k, v in doc.items() if k != "type"})

    names = " | ".join(f'{{"type": "{n}", ...{n}}}' for n in options)
    return _Kind(names, encode=encode, decode=decode)


def _value_class(type_name: str) -> type:
    return registered_types()[type_name].value_class


def _struct(type_name: str, cls: type, **fields: _Kind) -> Codec:
    """A codec for an attrs message class: a msgpack map with one key per field."""

    def encode(value: Any) -> Any:
        return {name: kind.encode(getattr(value, name)) for name, kind in fields.items()}

    def decode(doc: Any) -> Any:
        if not isinstance(doc, dict):
            raise CodecError(f"expected a map, got {type(doc).__name__}")
        kwargs = {}
        # Unknown keys are ignored (a newer publisher may add fields); a missing key takes the
        # field's default, so a third-party client may leave out e.g. the header.
        for name, kind in fields.items():
            if name in doc:
                try:
                    kwargs[name] = kind.decode(doc[name])
                except Exception as exc:
                    raise CodecError(f"field {name!r}: {exc}") from exc
        try:
            return cls(**kwargs)
        except TypeError as exc:
            raise CodecError(str(exc)) from exc

    schema = "{" + ", ".join(f'"{name}": {kind.describe}' for name, kind in fields.items()) + "}"
    return Codec(type_name, encode, decode, schema)


def _plain(type_name: str, describe: str) -> Codec:
    # The document is the value itself; decode_value checks it with the type's validate().
    return Codec(type_name, lambda v: v, lambda d: d, describe)


def _builtin_codecs() -> dict[str, Codec]:
    header = _struct("Header", m.Header, stamp_ns=_scalar("int (ns since the Unix epoch)"),
                     frame_id=_scalar("str"))
    h = _nested(header)
    image = _struct("Image", m.ImageMsg, data=_ndarray("HxWxC (|u1; <u2 for mono16 and 16UC1)"),
                    encoding=_scalar("str (rgb8, bgr8, rgba8, bgra8, mono8, mono16, 16UC1)"), header=h)
    compressed = _struct("CompressedImage", m.CompressedImageMsg, data=_scalar("bin"),
                         format=_scalar("str (jpeg, png, ...)"), header=h)
    detections = _struct(
        "Detections", m.DetectionsMsg, boxes=_vector("[[x1, y1, x2, y2] float, ...]"),
        labels=_scalar("[str, ...]"),
        scores=_vector("[float, ...]"), image=_optional(_nested(image)), header=h,
    )
    trackings = _struct(
        "Trackings", m.TrackingsMsg, ids=_vector("[int, ...]"), labels=_scalar("[str, ...]"),
        boxes=_vector("[[x1, y1, x2, y2] float, ...]"), centroids=_vector("[[x, y] float, ...]"),
        estimated_velocities=_vector("[[vx, vy] float, ...]"), image=_optional(_nested(image)), header=h,
    )
    pose = _struct("Pose", m.PoseMsg, position=_vector("[x, y, z] float"),
                   orientation=_vector("[x, y, z, w] float"), header=h)
    twist = _struct("Twist", m.TwistMsg, linear=_vector("[x, y, z] float"),
                    angular=_vector("[x, y, z] float"), header=h)
    point = _struct("Point", m.PointMsg, x=_scalar("float"), y=_scalar("float"), z=_scalar("float"), header=h)
    floats = _vector("[float, ...]")
    trajectory_point = _struct(
        "JointTrajectoryPoint", m.JointTrajectoryPointMsg, positions=floats, velocities=floats,
        accelerations=floats, effort=floats, time_from_start=_scalar("float (s)"),
    )
    codecs = [
        _plain("String", "str"),
        _struct("StreamingString", m.StreamingStringMsg, data=_scalar("str"), stream=_scalar("bool"),
                done=_scalar("bool"), header=h),
        _plain("Bool", "bool"),
        _plain("Int32", "int"),
        _plain("Int64", "int"),
        _plain("Float32", "float"),
        _plain("Float64", "float"),
        _plain("Float32MultiArray", "ndarray <f4, any shape"),
        _plain("Float64MultiArray", "ndarray <f8, any shape"),
        image,
        compressed,
        _struct("Audio", m.AudioMsg, data=_ndarray("1-D interleaved samples (<i2 or <f4)"),
                sample_rate=_scalar("int (Hz)"), channels=_scalar("int"), header=h),
        _struct("Video", m.VideoMsg,
                frames=_list_of(_tagged({"Image": image, "CompressedImage": compressed})), header=h),
        detections,
        _list_codec("DetectionsMultiSource", detections),
        trackings,
        _list_codec("TrackingsMultiSource", trackings),
        _struct("PointsOfInterest", m.PointsOfInterestMsg, points=_vector("[[x, y] float, ...]"),
                image=_optional(_nested(image)), header=h),
        point,
        _alias(point, "PointStamped"),
        pose,
        _alias(pose, "PoseStamped"),
        twist,
        _struct("Odometry", m.OdometryMsg, pose=_nested(pose), twist=_nested(twist),
                child_frame_id=_scalar("str"), header=h),
        _struct("JointState", m.JointStateMsg, name=_scalar("[str, ...]"), position=floats, velocity=floats,
                effort=floats, header=h),
        trajectory_point,
        _struct("JointTrajectory", m.JointTrajectoryMsg, joint_names=_scalar("[str, ...]"),
                points=_list_of(_nested(trajectory_point)), header=h),
        _struct("JointJog", m.JointJogMsg, joint_names=_scalar("[str, ...]"), displacements=floats,
                velocities=floats, duration=_scalar("float (s)"), header=h),
        _struct("OccupancyGrid", m.OccupancyGridMsg, data=_ndarray("HxW |i1 (-1 unknown, 0..100)"),
                resolution=_scalar("float (m/cell)"), origin=_nested(pose), header=h),
        _struct("LaserScan", m.LaserScanMsg, angle_min=_scalar("float"), angle_max=_scalar("float"),
                angle_increment=_scalar("float"), time_increment=_scalar("float"),
                scan_time=_scalar("float"), range_min=_scalar("float"), range_max=_scalar("float"),
                ranges=_ndarray("1-D <f4"), intensities=_ndarray("1-D <f4"), header=h),
        _struct("ComponentStatus", m.ComponentStatusMsg, component=_scalar("str"),
                lifecycle_state=_scalar("str"), health=_scalar("str (HEALTHY, ALGORITHM_FAILURE, ...)"),
                message=_scalar("str"), header=h),
    ]
    table = {c.type_name: c for c in codecs}
    table["Header"] = header
    limits = {
        **dict.fromkeys(("Bool", "Int32", "Int64", "Float32", "Float64"), _SCALAR_LIMITS),
        "String": _TEXT_LIMITS,
        **dict.fromkeys(("Image", "CompressedImage", "Audio", "OccupancyGrid", "LaserScan", "Float32MultiArray",
                         "Float64MultiArray"), _ARRAY_LIMITS),
        **dict.fromkeys(("Detections", "Trackings", "PointsOfInterest"), _PERCEPTION_LIMITS),
        **dict.fromkeys(("DetectionsMultiSource", "TrackingsMultiSource", "Video"), _BUNDLE_LIMITS),
        "JointTrajectory": _TRAJECTORY_LIMITS,
    }
    # Everything else (Header, StreamingString, Pose, Twist, Odometry, JointState, ...) is a fixed-shape message.
    return {name: attrs.evolve(codec, limits=limits.get(name, _STRUCT_LIMITS)) for name, codec in table.items()}


def _alias(codec: Codec, type_name: str) -> Codec:
    """The same document under another type name (e.g. PoseStamped travels as Pose)."""
    return attrs.evolve(codec, type_name=type_name)


def _list_codec(type_name: str, item: Codec) -> Codec:
    """A multi-source type: a msgpack list of ``item`` documents."""
    kind = _list_of(_nested(item))
    return Codec(type_name, kind.encode, kind.decode, kind.describe)


_lock = threading.Lock()
_codecs: dict[str, Codec] = _builtin_codecs()


def register_codec(type_name: str, encode: Callable[[Any], Any], decode: Callable[[Any], Any],
                   *, schema: str = "user-defined", limits: DecodeLimits | None = None) -> None:
    """Teach the Zenoh adapter a message type registered with ``add_additional_datatypes``.

    ``encode(value)`` returns a msgpack-able document (dicts, lists, str, int, float, bool,
    None, bytes, and numpy arrays, which travel without copies); ``decode(document)`` returns
    the value (it is then checked with the type's ``validate``). ``schema`` describes the
    document for :func:`describe_schemas`. ``limits`` bound what decoding a received sample may
    cost (default :data:`DEFAULT_DECODE_LIMITS`: documents up to 64 MiB, lists up to 262,144
    items; see :class:`DecodeLimits`). Registering again replaces the codec.
    """
    if not isinstance(type_name, str) or not type_name:
        raise CodecError(f"type_name must be a non-empty str, got {type_name!r}")
    if not callable(encode) or not callable(decode):
        raise CodecError(f"codec for {type_name!r}: encode and decode must be callables")
    if limits is not None and not isinstance(limits, DecodeLimits):
        raise CodecError(f"codec for {type_name!r}: limits must be a DecodeLimits, got {type(limits).__name__}")
    with _lock:
        _codecs[type_name] = Codec(type_name, encode, decode, schema, limits or DEFAULT_DECODE_LIMITS)


def _own_codec(msg_type: str | type[SupportedType]) -> Codec:
    if isinstance(msg_type, str):
        with _lock:
            codec = _codecs.get(msg_type)
        # A name with a codec but no registered type (register_codec alone) is looked up directly.
        return codec if codec is not None else codec_for(get_type(msg_type))
    return codec_for(msg_type)


def decode_limits(msg_type: str | type[SupportedType]) -> DecodeLimits:
    """The limits that samples of ``msg_type`` (a type or its registered name) are decoded under."""
    return _own_codec(msg_type).limits


def set_decode_limits(msg_type: str | type[SupportedType], limits: DecodeLimits | None = None,
                      **changes: int) -> DecodeLimits:
    """Change what decoding a sample of ``msg_type`` may cost, process-wide; returns the new limits.

    Pass whole ``limits``, or the fields to change, e.g. for a detector that reports more than
    262,144 boxes per frame::

        set_decode_limits("Detections", max_array_len=1_000_000, max_containers=1_000_000)

    Applies to subscriptions created afterwards and to those already open (every sample looks its
    codec up). A type without a codec of its own (a subtype decoded by its base's codec) changes
    the base type's limits.
    """
    name = _own_codec(msg_type).type_name
    with _lock:
        codec = _codecs[name]
        try:
            new = attrs.evolve(limits if limits is not None else codec.limits, **changes)
        except TypeError as exc:
            raise CodecError(f"set_decode_limits({name!r}): {exc}") from exc
        _codecs[name] = attrs.evolve(codec, limits=new)
    return new


def codec_for(msg_type: type[SupportedType]) -> Codec:
    """The codec of ``msg_type``: its own, else that of the nearest base type with the same value class.

    Raises :class:`CodecError` (with how to fix it) when there is none.
    """
    name = msg_type.type_name()
    with _lock:
        own = _codecs.get(name)
        if own is not None:
            return own
        for base in msg_type.__mro__[1:]:
            if (isinstance(base, type) and issubclass(base, SupportedType)
                    and base.value_class is msg_type.value_class and base.type_name() in _codecs):
                return _codecs[base.type_name()]
    raise CodecError(
        f"message type {name!r} has no Zenoh codec; register one with "
        f"agents_zenoh.register_codec({name!r}, encode, decode)"
    )


def encode_value(msg_type: type[SupportedType], value: Any, into: bytearray | None = None) -> bytes | bytearray:
    """The payload for ``value`` (already validated as ``msg_type``); ``into`` as in :func:`pack`."""
    codec = codec_for(msg_type)
    try:
        return pack(codec.encode(value), into)
    except Exception as exc:
        raise CodecError(f"cannot encode the value as {msg_type.type_name()}: {exc}") from exc


def decode_value(msg_type: type[SupportedType], payload: bytes | bytearray | memoryview) -> Any:
    """The value carried by ``payload``, validated as ``msg_type``; :class:`CodecError` if it does not decode."""
    codec = codec_for(msg_type)
    try:
        return msg_type.validate(codec.decode(unpack(payload, codec.limits)))
    except Exception as exc:
        raise CodecError(f"cannot decode the sample as {msg_type.type_name()}: {exc}") from exc


def describe_schemas() -> dict[str, str]:
    """Type name -> the msgpack document of that type, in words (the wire-format reference)."""
    with _lock:
        return {name: codec.schema for name, codec in sorted(_codecs.items())}
