"""Decode limits: what a received payload may cost, per type family, and the budget counted as it decodes.

Decoding is bounded (see :class:`DecodeLimits`): any peer may send anything, and a few megabytes
of msgpack can expand ~70x into small Python objects (an empty map is one byte on the wire, a
64-byte dict in memory). Each type's codec carries limits fitted to what the type can hold; the
document is measured and unpacked under them (:func:`agents_zenoh.codecs.framing.unpack`), and a
payload that exceeds one is rejected with a :class:`CodecError` before it costs more than a fixed
multiple of its size.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import attrs
from attrs import define, field

from agents_core.support.bounded_json import JsonLimits
from agents_core.types import is_builtin_type

from .errors import CodecError

if TYPE_CHECKING:
    from agents_core.supported_types import SupportedType

__all__ = [
    "DEFAULT_DECODE_LIMITS",
    "MAX_DIM",
    "MAX_NDIM",
    "STRUCT_LIMITS",
    "DecodeLimits",
    "counting_hooks",
    "json_limits",
    "limits_for",
]

_KIB, _MIB = 1024, 1024 * 1024
#: The most dimensions a received array may have. Numpy refuses more than 64; no message needs more than a handful.
MAX_NDIM = 32
#: The largest dimension of a received array: ROS 2 sizes are uint32, and no real array in one sample is longer.
MAX_DIM = 2**32 - 1
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

# The built-in types, by what their documents hold (see _TYPE_LIMITS):
# a bool / int / float: no containers at all.
_SCALAR_LIMITS = DecodeLimits(max_document_bytes=1 * _KIB, max_str_len=1 * _KIB, max_bin_len=1 * _KIB,
                              max_array_len=0, max_map_len=0, max_arrays=1, max_maps=1)
# String: one str (long LLM outputs included, up to 16 MiB); no containers.
_TEXT_LIMITS = DecodeLimits(max_document_bytes=16 * _MIB, max_str_len=16 * _MIB, max_bin_len=1 * _KIB,
                            max_array_len=0, max_map_len=0, max_arrays=1, max_maps=1)
# Fixed-shape messages (Pose, Header, StreamingString, JointState, ...): a few maps, lists of at
# most one value per joint; the only long part is a string (StreamingString.data).
STRUCT_LIMITS = DecodeLimits(max_document_bytes=16 * _MIB, max_str_len=16 * _MIB, max_bin_len=64 * _KIB,
                              max_array_len=65_536, max_map_len=64, max_arrays=256, max_maps=256)
# One array plus a few scalars (Image, Audio, OccupancyGrid, LaserScan, multi-arrays,
# CompressedImage): a third party may put the array's bytes inside the document, so the document
# may be large, but it holds a handful of small maps and the shape list, nothing more.
_ARRAY_LIMITS = DecodeLimits(max_document_bytes=256 * _MIB, max_str_len=64 * _KIB, max_bin_len=256 * _MIB,
                             max_array_len=MAX_NDIM, max_map_len=64, max_arrays=256, max_maps=256)
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
#: The module of the framework's own message types (each has limits fitted to its schema).


def limits_for(msg_type: type[SupportedType]) -> DecodeLimits:
    """The limits a codec derived for ``msg_type`` decodes under: its family's, else the default."""
    name = msg_type.type_name()
    if name in _TYPE_LIMITS:
        return _TYPE_LIMITS[name]
    # Every other built-in type (Header, StreamingString, Pose, Twist, Odometry, ...) is a fixed-shape message.
    return STRUCT_LIMITS if is_builtin_type(msg_type) else DEFAULT_DECODE_LIMITS


def json_limits(limits: DecodeLimits) -> JsonLimits:
    """The same bounds for a document that comes as JSON rather than msgpack (a raw client's request).

    Sizes and counts carry over one to one (a msgpack map is a JSON object); JSON adds a depth
    limit (msgpack's unpacker stops at 1024 levels by itself), a 64-bit integer range (all msgpack
    can carry) and the refusal of NaN / Infinity (see :class:`~agents_core.support.bounded_json.JsonLimits`).
    """
    return JsonLimits(max_bytes=limits.max_document_bytes, max_str_len=limits.max_str_len,
                      max_objects=limits.max_maps, max_arrays=limits.max_arrays,
                      max_object_len=limits.max_map_len, max_array_len=limits.max_array_len,
                      max_expansion=limits.max_expansion)


def counting_hooks(limits: DecodeLimits, size: int, resolve: Callable[[dict[Any, Any]], Any]) -> dict[str, Any]:
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

