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

import array
import contextlib
import functools
import importlib
import math
import re
import threading
import types
import typing
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import attrs
import msgpack  # type: ignore[import-untyped]  # msgpack ships no type information
import numpy as np
import numpy.typing as npt
from attrs import define, field

from agents_core import messages as m
from agents_core.errors import TypeValidationError
from agents_core.registry import NotRegisteredError, Registry
from agents_core.supported_types import SupportedType, get_type, registered_types, shares_value_class
from agents_core.types import is_builtin_type

__all__ = [
    "DEFAULT_DECODE_LIMITS",
    "MSGPACK",
    "Codec",
    "CodecError",
    "DecodeLimits",
    "MissingCodecError",
    "builtin_schema_names",
    "codec_for",
    "decode_limits",
    "decode_value",
    "decoder_for",
    "derive_codec",
    "describe_schemas",
    "encode_value",
    "pack",
    "register_codec",
    "schema_list",
    "schema_name",
    "set_decode_limits",
    "unpack",
    "update_schema_doc",
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
# Poses (Path, PoseArray): two maps (pose, header) and two lists each; up to 16,384 poses.
_POSES_LIMITS = attrs.evolve(_PERCEPTION_LIMITS, max_maps=2 * 16_384 + 64, max_arrays=2 * 16_384 + 64)


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
    bins: list[tuple[int, int]] = []
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


_NO_DOCUMENT: Any = object()


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
    """How one field of a structured type travels (see :func:`derive_codec`)."""

    def __init__(self, describe: str, encode: Callable[[Any], Any] = lambda v: v,
                 decode: Callable[[Any], Any] = lambda d: d) -> None:
        self.describe = describe
        self.encode = encode
        self.decode = decode


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


# A structured array's layout on the wire: at most this many fields, each at most this many bytes a record.
_MAX_RECORD_FIELDS, _MAX_RECORD_BYTES = 256, 65_536
_FIELD_DTYPE_RE = re.compile(r"^[<|][iuf][1248]$")


def _structured(describe: str | None) -> _Kind:
    """A numpy structured array (e.g. point cloud points): its field layout, its shape, and its raw bytes."""

    def encode(arr: npt.NDArray[Any]) -> Any:
        fields = [[name, offset, dtype.str] for name, (dtype, offset, *_) in arr.dtype.fields.items()]  # type: ignore[union-attr]
        raw = np.ascontiguousarray(arr).reshape(-1).view(np.uint8)
        return {"fields": fields, "itemsize": arr.dtype.itemsize, "shape": list(arr.shape), "data": raw}

    def decode(doc: Any) -> Any:
        if not isinstance(doc, dict) or not {"fields", "itemsize", "shape", "data"} <= doc.keys():
            raise CodecError("expected a map with fields, itemsize, shape and data")
        fields, itemsize, shape, raw = doc["fields"], doc["itemsize"], doc["shape"], doc["data"]
        if not isinstance(itemsize, int) or isinstance(itemsize, bool) or not 0 < itemsize <= _MAX_RECORD_BYTES:
            raise CodecError(f"itemsize {itemsize!r} is not an int from 1 to {_MAX_RECORD_BYTES}")
        if not isinstance(fields, list) or not 0 < len(fields) <= _MAX_RECORD_FIELDS:
            raise CodecError(f"fields must be a list of 1 to {_MAX_RECORD_FIELDS} [name, offset, dtype] entries")
        names, formats, offsets = [], [], []
        for entry in fields:
            if (not isinstance(entry, list) or len(entry) != 3 or not isinstance(entry[0], str)
                    or not isinstance(entry[1], int) or isinstance(entry[1], bool) or not isinstance(entry[2], str)
                    or not _FIELD_DTYPE_RE.match(entry[2])):
                raise CodecError(f"field entry {entry!r} is not [name, offset, dtype] with a numeric dtype "
                                 "such as '<f4'")
            name, offset, dtype = entry
            if not 0 <= offset <= itemsize - np.dtype(dtype).itemsize:
                raise CodecError(f"field {name!r} at offset {offset} does not fit a {itemsize}-byte record")
            names.append(name)
            formats.append(dtype)
            offsets.append(offset)
        if (not isinstance(shape, list) or len(shape) > 2
                or not all(isinstance(d, int) and not isinstance(d, bool) and 0 <= d <= _MAX_DIM for d in shape)):
            raise CodecError(f"shape {shape!r} is not a list of at most 2 sizes")
        try:
            dtype_ = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": itemsize})
        except (TypeError, ValueError) as exc:
            raise CodecError(f"the fields do not make a record layout: {exc}") from exc
        if not isinstance(raw, np.ndarray) or raw.dtype != np.uint8 or raw.ndim != 1:
            raise CodecError("data must be a 1-D |u1 ndarray")
        if raw.size != math.prod(shape) * itemsize:
            raise CodecError(f"data has {raw.size} bytes; {shape} records of {itemsize} bytes need "
                             f"{math.prod(shape) * itemsize}")
        return raw.view(dtype_).reshape(tuple(shape))

    schema = ('{"fields": [[name, offset, dtype], ...], "itemsize": int, "shape": [int, ...], '
              '"data": ndarray |u1 (the records\' bytes)}')
    return _Kind(describe or schema, encode=encode, decode=decode)


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


def _tagged(options: Mapping[str, Codec], classes: Mapping[type, str]) -> _Kind:
    """One of several structured types, told apart by an added ``"type"`` key."""

    def encode(value: Any) -> Any:
        name = classes[type(value)]
        return {"type": name, **options[name].encode(value)}

    def decode(doc: Any) -> Any:
        if not isinstance(doc, dict) or doc.get("type") not in options:
            raise CodecError(f"expected a map with 'type' one of {sorted(options)}")
        return options[doc["type"]].decode({k: v for k, v in doc.items() if k != "type"})

    names = " | ".join(f'{{"type": "{n}", ...{n}}}' for n in options)
    return _Kind(names, encode=encode, decode=decode)


# -- codecs derived from value classes ----------------------------------------------------------

#: What a plain (non-attrs) value class is called in the schemas.
_PLAIN_NAMES: dict[type, str] = {str: "str", bool: "bool", int: "int", float: "float", bytes: "bin"}


def schema_name(value_class: type) -> str:
    """The name a value class has in the schemas: its registered type's (``ImageMsg`` -> ``Image``)."""
    for name, t in registered_types().items():
        if t.value_class is value_class:
            return name
    return value_class.__name__.removesuffix("Msg")


def _field_hints(cls: type) -> dict[str, Any]:
    try:
        return typing.get_type_hints(cls)
    except Exception:
        # A class defined in a function may name locals in string annotations: use the annotations that
        # are already objects; the others travel as they are (the class's converters see them on decode).
        return {f.name: f.type for f in attrs.fields(cls) if f.type is not None and not isinstance(f.type, str)}


def _is_union(hint: Any) -> bool:
    return typing.get_origin(hint) in (typing.Union, types.UnionType)


def _kind_for(hint: Any, spec: m.Wire, seen: dict[type, Codec]) -> _Kind:
    """The wire form of a field with type ``hint`` (see :class:`agents_core.messages.Wire` for ``spec``)."""
    origin = typing.get_origin(hint)
    if hint is np.ndarray or origin is np.ndarray:
        if spec.structured:
            return _structured(spec.describe)
        if spec.as_list:
            return _vector(spec.describe or "[float, ...]")
        return _ndarray(spec.describe or "any shape")
    if _is_union(hint):
        options = [a for a in typing.get_args(hint) if a is not type(None)]
        optional = len(options) < len(typing.get_args(hint))
        if len(options) == 1:
            kind = _kind_for(options[0], m.Wire(), seen)
        elif all(attrs.has(a) for a in options):
            codecs = {schema_name(a): _derived_struct(a, seen) for a in options}
            kind = _tagged(codecs, {a: schema_name(a) for a in options})
        else:
            kind = _Kind(" | ".join(_describe_plain(a) for a in options))
        kind = _optional(kind) if optional else kind
        if spec.describe:
            kind.describe = spec.describe
        return kind
    if isinstance(hint, type) and attrs.has(hint):
        return _nested(_derived_struct(hint, seen))
    if origin is list:
        (item,) = typing.get_args(hint) or (Any,)
        if (isinstance(item, type) and attrs.has(item)) or _is_union(item):
            kind = _list_of(_kind_for(item, m.Wire(), seen))
            if spec.describe:
                kind.describe = spec.describe
            return kind
    return _Kind(spec.describe or _describe_plain(hint))


def _describe_plain(hint: Any) -> str:
    if typing.get_origin(hint) is list:
        (item,) = typing.get_args(hint) or (Any,)
        return f"[{_describe_plain(item)}, ...]"
    if isinstance(hint, type):
        return _PLAIN_NAMES.get(hint, hint.__name__)
    return "any"


def _derived_struct(cls: type, seen: dict[type, Codec] | None = None) -> Codec:
    """The codec of an attrs message class: a msgpack map with one key per field, in field order."""
    seen = {} if seen is None else seen
    if cls in seen:
        return seen[cls]
    hints = _field_hints(cls)
    fields: dict[str, _Kind] = {}
    for f in attrs.fields(cls):
        if not f.init:
            continue  # derived state, rebuilt by the class
        spec = f.metadata.get("wire", m.Wire())
        fields[f.name] = _kind_for(hints.get(f.name, Any), spec, seen)

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
    codec = Codec(schema_name(cls), encode, decode, schema)
    seen[cls] = codec
    return codec


def _plain(type_name: str, describe: str) -> Codec:
    # The document is the value itself; decode_value checks it with the type's validate().
    return Codec(type_name, lambda v: v, lambda d: d, describe)


def derive_codec(msg_type: type[SupportedType]) -> Codec | None:
    """The codec of ``msg_type`` derived from its value class, or None when it has no derivable one.

    An attrs value class travels as a map of its fields (nested attrs values and headers as
    maps, numpy arrays out of band, small vectors as lists where the field says so); a builtin
    value class (str, bool, int, float, bytes) or a numpy array with a ``dtype`` as itself; a
    list type with an ``item`` type as a list of the item's documents.
    """
    name = msg_type.type_name()
    value_class = msg_type.value_class
    if attrs.has(value_class):
        return attrs.evolve(_derived_struct(value_class), type_name=name)
    if value_class in _PLAIN_NAMES:
        return _plain(name, _PLAIN_NAMES[value_class])
    dtype = getattr(msg_type, "dtype", None)
    if value_class is np.ndarray and dtype is not None:
        return _plain(name, f"ndarray {np.dtype(dtype).str}, any shape")
    if value_class is object and getattr(msg_type, "_ros_type", None) is not None:
        return _ros_codec(msg_type.message_class(), name)
    item = getattr(msg_type, "item", None)
    if value_class is list and isinstance(item, type) and issubclass(item, SupportedType):
        item_codec = codec_for(item)
        kind = _list_of(_nested(item_codec))
        return Codec(name, kind.encode, kind.decode, kind.describe)
    return None


# -- codecs of ROS message classes (a type declared the upstream way: _ros_type, no value class) ----

# ROS primitive -> (numpy dtype, array.array typecode) for numeric sequences and arrays.
_ROS_NUMERIC: dict[str, tuple[str, str]] = {
    "float": ("<f4", "f"), "double": ("<f8", "d"), "int8": ("|i1", "b"), "uint8": ("|u1", "B"),
    "int16": ("<i2", "h"), "uint16": ("<u2", "H"), "int32": ("<i4", "i"), "uint32": ("<u4", "I"),
    "int64": ("<i8", "q"), "uint64": ("<u8", "Q"),
}
_ROS_SEQUENCE = re.compile(r"^sequence<([\w/]+)(?:, \d+)?>$|^([\w/]+)\[(\d*)\]$")


@functools.cache
def _ros_class(name: str) -> type:
    package, _, message = name.partition("/")
    module = importlib.import_module(f"{package}.msg")
    cls: type = getattr(module, message)
    return cls


def _ros_codec(ros_class: type, type_name: str) -> Codec:
    """A ROS message as a msgpack map of its fields (cached per class)."""
    return _ros_codec_cached(ros_class, type_name)


@functools.cache
def _ros_codec_cached(ros_class: Any, type_name: str) -> Codec:
    """A ROS message as a msgpack map of its fields: nested messages as maps, numeric sequences as arrays."""
    fields: dict[str, str] = ros_class.get_fields_and_field_types()

    def encode_field(kind: str, value: Any) -> Any:
        seq = _ROS_SEQUENCE.match(kind)
        item = (seq.group(1) or seq.group(2)) if seq else None
        if item in _ROS_NUMERIC:
            return np.asarray(value, dtype=_ROS_NUMERIC[item][0])
        if item is not None:
            return [encode_field(item, v) for v in value]
        if "/" in kind:
            return _ros_codec(_ros_class(kind), kind).encode(value)
        return value

    def decode_field(kind: str, doc: Any) -> Any:
        seq = _ROS_SEQUENCE.match(kind)
        item = (seq.group(1) or seq.group(2)) if seq else None
        if item in _ROS_NUMERIC:
            dtype, typecode = _ROS_NUMERIC[item]
            values = np.asarray(doc, dtype=dtype)
            if seq is not None and seq.group(3):  # a fixed-size array: rosidl keeps it as numpy
                return values.astype(values.dtype.newbyteorder("="))
            out = array.array(typecode)
            out.frombytes(np.ascontiguousarray(values, dtype=values.dtype.newbyteorder("=")).tobytes())
            return out
        if item is not None:
            if not isinstance(doc, list):
                raise CodecError(f"expected a list, got {type(doc).__name__}")
            return [decode_field(item, d) for d in doc]
        if "/" in kind:
            return _ros_codec(_ros_class(kind), kind).decode(doc)
        return doc

    def encode(value: Any) -> Any:
        return {name: encode_field(kind, getattr(value, name)) for name, kind in fields.items()}

    def decode(doc: Any) -> Any:
        if not isinstance(doc, dict):
            raise CodecError(f"expected a map, got {type(doc).__name__}")
        message = ros_class()
        for name, kind in fields.items():
            if name in doc:
                try:
                    setattr(message, name, decode_field(kind, doc[name]))
                except Exception as exc:
                    raise CodecError(f"field {name!r}: {exc}") from exc
        return message

    schema = "{" + ", ".join(f'"{name}": {kind}' for name, kind in fields.items()) + "}"
    return Codec(type_name, encode, decode, f"{schema} (the fields of the ROS message)")


# The built-in types' decode limits, by what their documents hold (see the *_LIMITS above).
_TYPE_LIMITS: dict[str, DecodeLimits] = {
    **dict.fromkeys(("Bool", "Int32", "Int64", "Float32", "Float64"), _SCALAR_LIMITS),
    "String": _TEXT_LIMITS,
    **dict.fromkeys(("Image", "CompressedImage", "Audio", "OccupancyGrid", "LaserScan", "Float32MultiArray",
                     "Float64MultiArray", "RGBD", "PointCloud2"), _ARRAY_LIMITS),
    **dict.fromkeys(("Path", "PoseArray"), _POSES_LIMITS),
    **dict.fromkeys(("Detections", "Trackings", "PointsOfInterest"), _PERCEPTION_LIMITS),
    **dict.fromkeys(("DetectionsMultiSource", "TrackingsMultiSource", "Video"), _BUNDLE_LIMITS),
    "JointTrajectory": _TRAJECTORY_LIMITS,
}
# Every other built-in type (Header, StreamingString, Pose, Twist, Odometry, JointState, ...) is a fixed-shape message.


class MissingCodecError(CodecError, NotRegisteredError):
    """A message type has no Zenoh codec (neither registered nor derivable)."""


_codecs: Registry[Codec] = Registry(
    "Zenoh codec", missing_error=MissingCodecError, missing_text="message type {name} has no {kind}",
    class_name=lambda cls: cls.type_name() if issubclass(cls, SupportedType) else cls.__name__,
    hint="register one with agents_zenoh.register_codec({name}, encode, decode), or register the type "
         "with add_additional_datatypes to derive it from its attrs value class",
)
_lock = threading.Lock()  # makes derive-then-register one step


def _limits_for(msg_type: type[SupportedType]) -> DecodeLimits:
    name = msg_type.type_name()
    if name in _TYPE_LIMITS:
        return _TYPE_LIMITS[name]
    return _STRUCT_LIMITS if is_builtin_type(msg_type) else DEFAULT_DECODE_LIMITS


def _register_derived(msg_type: type[SupportedType]) -> Codec | None:
    codec = derive_codec(msg_type)
    if codec is None:
        return None
    codec = attrs.evolve(codec, limits=_limits_for(msg_type))
    with _lock:
        existing = _codecs.find(msg_type.type_name())
        return existing if existing is not None else _codecs.register(msg_type.type_name(), codec)


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
    _codecs.register(type_name, Codec(type_name, encode, decode, schema, limits or DEFAULT_DECODE_LIMITS),
                     replace=True)


def _own_codec(msg_type: str | type[SupportedType]) -> Codec:
    if isinstance(msg_type, str):
        codec = _codecs.find(msg_type)
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
        codec = _codecs.get(name)
        try:
            new = attrs.evolve(limits if limits is not None else codec.limits, **changes)
        except TypeError as exc:
            raise CodecError(f"set_decode_limits({name!r}): {exc}") from exc
        _codecs.register(name, attrs.evolve(codec, limits=new), replace=True)
    return new


def codec_for(msg_type: type[SupportedType]) -> Codec:
    """The codec of ``msg_type``: its own, else its nearest base type's with the same value class
    (the registry's one subclass rule), else one derived from its value class if the type is registered.

    Raises :class:`CodecError` (with how to fix it) when there is none.
    """
    found = _codecs.find_for_class(msg_type, inherits=shares_value_class)
    if found is not None:
        return found
    name = msg_type.type_name()
    if registered_types().get(name) is msg_type:
        derived = _register_derived(msg_type)
        if derived is not None:
            return derived
    raise _codecs.missing(name)


def encode_value(msg_type: type[SupportedType], value: Any, into: bytearray | None = None) -> bytes | bytearray:
    """The payload for ``value`` (already validated as ``msg_type``); ``into`` as in :func:`pack`."""
    codec = codec_for(msg_type)
    try:
        return pack(codec.encode(value), into)
    except Exception as exc:
        raise CodecError(f"cannot encode the value as {msg_type.type_name()}: {exc}") from exc


def decoder_for(msg_type: type[SupportedType]) -> Callable[[bytes | bytearray | memoryview], Any]:
    """:func:`decode_value` for one type, with its codec and limits looked up once (a subscriber's hot path).

    The codec is the one registered when this is called.
    """
    codec = codec_for(msg_type)
    decode, limits, validate, name = codec.decode, codec.limits, msg_type.validate, msg_type.type_name()

    def decode_payload(payload: bytes | bytearray | memoryview) -> Any:
        try:
            return validate(decode(unpack(payload, limits)))
        except Exception as exc:
            raise CodecError(f"cannot decode the sample as {name}: {exc}") from exc

    return decode_payload


def decode_value(msg_type: type[SupportedType], payload: bytes | bytearray | memoryview) -> Any:
    """The value carried by ``payload``, validated as ``msg_type``; :class:`CodecError` if it does not decode."""
    codec = codec_for(msg_type)
    try:
        return msg_type.validate(codec.decode(unpack(payload, codec.limits)))
    except Exception as exc:
        raise CodecError(f"cannot decode the sample as {msg_type.type_name()}: {exc}") from exc


def describe_schemas() -> dict[str, str]:
    """Type name -> the msgpack document of that type, in words (the wire-format reference).

    Every registered type whose codec can be derived is listed, with ``Header`` and the codecs
    registered with :func:`register_codec`.
    """
    for msg_type in registered_types().values():
        with contextlib.suppress(CodecError):
            codec_for(msg_type)
    return {name: codec.schema for name, codec in sorted(_codecs.snapshot().items())}


def schema_list(names: Iterable[str] | None = None) -> str:
    """The Markdown list of schemas in ``docs/zenoh-wire-format.md`` ("- **Name**: `schema`" lines)."""
    schemas = describe_schemas()
    chosen = sorted(schemas) if names is None else sorted(names)
    # Header first: most schemas refer to it.
    chosen = ["Header", *(n for n in chosen if n != "Header")] if "Header" in chosen else chosen
    return "".join(f"- **{name}**: `{schemas[name]}`\n" for name in chosen)


def builtin_schema_names() -> list[str]:
    """The schemas the wire-format document lists: Header and every framework type."""
    return ["Header", *(n for n, t in registered_types().items() if is_builtin_type(t))]


def update_schema_doc(path: str) -> bool:
    """Rewrite the schema list of the wire-format document at ``path`` from the registry; True if it changed.

    Run ``python -m agents_zenoh.codecs docs/zenoh-wire-format.md`` after adding a type.
    """
    with open(path, encoding="utf-8") as fh:
        text = fh.read()
    match = _SCHEMA_LIST.search(text)
    if match is None:
        raise ValueError(f"{path} has no schema list (lines '- **Name**: `...`' starting with Header)")
    new = text[:match.start()] + schema_list(builtin_schema_names()) + text[match.end():]
    if new != text:
        with open(path, "w", encoding="utf-8") as fh:
            fh.write(new)
    return new != text


#: The schema list in the wire-format document: consecutive "- **Name**: `...`" lines from Header on.
_SCHEMA_LIST = re.compile(r"^- \*\*Header\*\*: `.*?\n(?:- \*\*\w+\*\*: `.*\n)*", re.M)


def _init_builtin() -> None:
    _codecs.register("Header", attrs.evolve(_derived_struct(m.Header), limits=_STRUCT_LIMITS))
    for msg_type in registered_types().values():
        if is_builtin_type(msg_type):
            _register_derived(msg_type)


_init_builtin()


if __name__ == "__main__":  # pragma: no cover - a maintenance command
    import sys

    for doc_path in sys.argv[1:]:
        print(f"{doc_path}: {'updated' if update_schema_doc(doc_path) else 'up to date'}")
