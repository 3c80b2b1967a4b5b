"""Value classes: the plain Python form of every message that flows between components.

Simple types travel as builtins (``str``, ``bool``, ``int``, ``float``) or numpy arrays. Structured
types are small attrs classes defined here, each with a :class:`Header` (stamp and frame_id)
that transport conversions preserve end to end. Constructing a value validates it and raises
:class:`~agents_core.errors.TypeValidationError` naming the field that is wrong.

Values are delivered zero-copy on the memory transport: every subscriber receives the same
object, so treat received values (and their numpy arrays) as read-only.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from typing import Any, TypeVar

import attrs
import numpy as np
import numpy.typing as npt
from attrs import define, field

from .errors import TypeValidationError

__all__ = [
    "DEPTH_ENCODINGS",
    "IMAGE_ENCODINGS",
    "MAX_ARRAY_DIM",
    "MAX_IMAGE_SIDE",
    "POINT_FIELD_DTYPES",
    "AudioMsg",
    "CameraInfoMsg",
    "ComponentStatusMsg",
    "CompressedImageMsg",
    "DetectionsMsg",
    "Header",
    "ImageMsg",
    "ImuMsg",
    "JointJogMsg",
    "JointStateMsg",
    "JointTrajectoryMsg",
    "JointTrajectoryPointMsg",
    "LaserScanMsg",
    "MapMetaDataMsg",
    "NavSatFixMsg",
    "OccupancyGridMsg",
    "OdometryMsg",
    "PathMsg",
    "PointCloud2Msg",
    "PointMsg",
    "PointsOfInterestMsg",
    "PoseArrayMsg",
    "PoseMsg",
    "RGBDMsg",
    "StreamingStringMsg",
    "TrackingsMsg",
    "TwistMsg",
    "VideoMsg",
    "Wire",
    "as_numeric_array",
    "image_array",
    "values_equal",
    "wire",
]

#: Image encodings the core understands: name -> (numpy dtype, channel count).
IMAGE_ENCODINGS: dict[str, tuple[type[np.generic], int]] = {
    "rgb8": (np.uint8, 3),
    "bgr8": (np.uint8, 3),
    "rgba8": (np.uint8, 4),
    "bgra8": (np.uint8, 4),
    "mono8": (np.uint8, 1),
    "mono16": (np.uint16, 1),
    "16UC1": (np.uint16, 1),
    "32FC1": (np.float32, 1),
}

#: The largest height or width an :class:`ImageMsg` may have (pixels). Far beyond any sensor or
#: stitched panorama, and small enough that a row of it fits ROS 2's uint32 ``step``.
MAX_IMAGE_SIDE = 1 << 20
#: The largest dimension of any array field: ROS 2 sizes are uint32, and no array in one message is longer.
MAX_ARRAY_DIM = 2**32 - 1


def values_equal(a: Any, b: Any) -> bool:
    """Deep equality for message values (numpy arrays compared by dtype, shape and content)."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return (
            isinstance(a, np.ndarray)
            and isinstance(b, np.ndarray)
            and a.dtype == b.dtype
            and a.shape == b.shape
            and bool(np.array_equal(a, b, equal_nan=a.dtype.kind == "f"))
        )
    if attrs.has(type(a)):
        return type(a) is type(b) and all(
            values_equal(getattr(a, f.name), getattr(b, f.name)) for f in attrs.fields(type(a))
        )
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(values_equal(x, y) for x, y in zip(a, b, strict=True))
    return bool(a == b)


_M = TypeVar("_M")


def _named(cls: type[_M]) -> type[_M]:
    """Prefix the construction errors of an attrs message class with its name ("ImuMsg field 'x': ...")."""
    init = cls.__init__

    @functools.wraps(init)
    def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
        try:
            init(self, *args, **kwargs)
        except TypeValidationError as exc:
            if str(exc).startswith(cls.__name__):
                raise
            raise TypeValidationError(f"{cls.__name__} {exc}") from exc

    cls.__init__ = __init__  # type: ignore[method-assign]
    return cls


class _Message:
    """Mixin giving attrs message classes a numpy-aware ``==``."""

    def __eq__(self, other: object) -> bool:
        return values_equal(self, other)

    __hash__ = None  # type: ignore[assignment]  # mutable values: unhashable like lists


# -- field converters -------------------------------------------------------------------------


def _check_holds(arr: npt.NDArray[Any], name: str) -> None:
    """Refuse an array whose shape claims more elements than its memory holds, or absurd dimensions.

    A broadcast or overlapping view (zero or too-small strides) of a few bytes can claim terabytes:
    any code that copies it (a transport, ``np.ascontiguousarray``) would then allocate them all.
    """
    if any(d > MAX_ARRAY_DIM for d in arr.shape):
        raise TypeValidationError(f"field {name!r}: shape {arr.shape} has a dimension above {MAX_ARRAY_DIM}")
    if arr.flags.c_contiguous or arr.flags.f_contiguous or arr.size == 0:
        return  # the common case, checked by numpy's flags: each element has memory of its own
    # Sorted by stride, each dimension must step over everything the smaller ones span.
    span = arr.itemsize
    for stride, size in sorted((abs(st), n) for st, n in zip(arr.strides, arr.shape, strict=True) if n > 1):
        if stride < span:
            raise TypeValidationError(
                f"field {name!r}: shape {arr.shape} claims more elements than its data holds (a broadcast "
                "or overlapping view); pass a copy, e.g. np.ascontiguousarray(...)"
            )
        span = stride * size


def as_numeric_array(value: Any, dtype: type[np.generic] | None, name: str) -> npt.NDArray[Any]:
    """``value`` (an array or an array-like such as nested lists) as a numpy array, of ``dtype`` if given.

    Refuses, with :class:`TypeValidationError` naming ``name``: ragged nesting, non-numeric items,
    and values that ``dtype`` cannot hold (an integer out of its range, a finite float beyond
    float32's), rather than letting numpy wrap them round or turn them into inf.
    """
    try:
        arr = value if isinstance(value, np.ndarray) else np.asarray(value)
    except (TypeError, ValueError) as exc:  # ragged nesting: "inhomogeneous shape"
        raise TypeValidationError(f"field {name!r}: not a rectangular array ({exc})") from exc
    _check_holds(arr, name)
    if arr.dtype.kind not in "biuf":
        raise TypeValidationError(f"field {name!r}: expected numbers, got an array of {arr.dtype} "
                                  f"(from {type(value).__name__})")
    if dtype is None or arr.dtype == dtype:
        return arr
    target = np.dtype(dtype)
    if arr.size and target.kind in "iu" and arr.dtype.kind in "iuf":
        if arr.dtype.kind == "f" and not bool(np.all(np.isfinite(arr) & (arr == np.trunc(arr)))):
            raise TypeValidationError(f"field {name!r}: expected whole numbers for {target}, got fractions or "
                                      "non-finite values")
        info = np.iinfo(target)
        low, high = arr.min(), arr.max()
        if low < info.min or high > info.max:
            raise TypeValidationError(f"field {name!r}: values from {low} to {high} do not fit {target} "
                                      f"({info.min}..{info.max})")
    elif arr.size and target == np.float32 and arr.dtype.kind == "f" and arr.dtype.itemsize > 4:
        finite = arr[np.isfinite(arr)]
        if finite.size and float(np.abs(finite).max()) > float(np.finfo(np.float32).max):
            raise TypeValidationError(f"field {name!r}: values beyond float32's range")
    return arr.astype(target)


def _to_array(value: Any, dtype: type[np.generic], shape: tuple[int | None, ...], name: str) -> npt.NDArray[Any]:
    """``value`` as a numpy array of ``dtype`` whose shape matches ``shape`` (None = any size)."""
    arr = as_numeric_array(value, None, name)
    if arr.size == 0:
        try:
            arr = arr.reshape(tuple(0 if d is None else d for d in shape))
        except ValueError as exc:
            raise TypeValidationError(f"field {name!r}: cannot make a {dtype.__name__} array: {exc}") from exc
    arr = as_numeric_array(arr, dtype, name)
    if arr.ndim != len(shape) or any(d is not None and d != s for d, s in zip(shape, arr.shape, strict=True)):
        want = "x".join("N" if d is None else str(d) for d in shape)
        raise TypeValidationError(f"field {name!r}: expected shape {want}, got {arr.shape}")
    return arr


# Named converters, one per array field: mypy's attrs plugin types __init__ only from named functions.
def _boxes(value: Any) -> npt.NDArray[np.float32]:
    return _to_array(value, np.float32, (None, 4), "boxes")


def _scores(value: Any) -> npt.NDArray[np.float32]:
    return _to_array(value, np.float32, (None,), "scores")


def _ids(value: Any) -> npt.NDArray[np.int64]:
    return _to_array(value, np.int64, (None,), "ids")


def _centroids(value: Any) -> npt.NDArray[np.float32]:
    return _to_array(value, np.float32, (None, 2), "centroids")


def _estimated_velocities(value: Any) -> npt.NDArray[np.float32]:
    return _to_array(value, np.float32, (None, 2), "estimated_velocities")


def _points(value: Any) -> npt.NDArray[np.float32]:
    return _to_array(value, np.float32, (None, 2), "points")


def _position(value: Any) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (3,), "position")


def _orientation(value: Any) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (4,), "orientation")


def _linear(value: Any) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (3,), "linear")


def _angular(value: Any) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (3,), "angular")


def _position_vector(value: Any) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (None,), "position")


def _velocity(value: Any) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (None,), "velocity")


def _effort(value: Any) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (None,), "effort")


def _positions(value: Any) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (None,), "positions")


def _velocities(value: Any) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (None,), "velocities")


def _accelerations(value: Any) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (None,), "accelerations")


def _displacements(value: Any) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (None,), "displacements")


def _data(value: Any) -> npt.NDArray[np.int8]:
    return _to_array(value, np.int8, (None, None), "data")


def _ranges(value: Any) -> npt.NDArray[np.float32]:
    return _to_array(value, np.float32, (None,), "ranges")


def _intensities(value: Any) -> npt.NDArray[np.float32]:
    return _to_array(value, np.float32, (None,), "intensities")


def _field_error(attribute: attrs.Attribute[Any], expected: str, value: Any) -> TypeValidationError:
    return TypeValidationError(f"field {attribute.name!r}: expected {expected}, got {type(value).__name__}")


def _is_str(_: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    if not isinstance(value, str):
        raise _field_error(attribute, "str", value)


def _is_bool(_: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    if not isinstance(value, bool | np.bool_):
        raise _field_error(attribute, "bool", value)


def _is_number(_: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise _field_error(attribute, "a number", value)


def _is_str_list(_: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    if not isinstance(value, list | tuple) or not all(isinstance(item, str) for item in value):
        raise _field_error(attribute, "a list of str", value)


def _instance_of(cls: type[Any], optional: bool = False) -> Callable[[Any, attrs.Attribute[Any], Any], None]:
    def check(_: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
        if not (isinstance(value, cls) or (optional and value is None)):
            raise _field_error(attribute, cls.__name__, value)

    return check


@define(frozen=True)
class Wire:
    """How a field is described in the Zenoh wire-format schema (``docs/zenoh-wire-format.md``).

    ``describe`` replaces the description derived from the field's type (``"float (s)"`` rather
    than ``"float"``); ``as_list`` sends a small numpy array as a plain msgpack list (friendlier to
    third-party clients than an array descriptor) instead of an out-of-band array.
    """

    describe: str | None = None
    as_list: bool = False
    #: A numpy structured array (named fields at byte offsets): sent as its field layout plus its raw bytes.
    structured: bool = False


def wire(describe: str | None = None, *, as_list: bool = False, structured: bool = False) -> dict[str, Any]:
    """Field metadata for :class:`Wire`: ``field(..., metadata=wire("[x, y, z] float", as_list=True))``."""
    return {"wire": Wire(describe, as_list, structured)}


#: Small vectors that travel as plain msgpack lists.
_FLOATS = wire("[float, ...]", as_list=True)
_BOXES = wire("[[x1, y1, x2, y2] float, ...]", as_list=True)


def _now_ns() -> int:
    return time.time_ns()


def _header_field() -> Any:
    return field(factory=Header, validator=_instance_of(Header))


# -- header -----------------------------------------------------------------------------------


@_named
@define(eq=False)
class Header(_Message):
    """When and in which coordinate frame a value was produced.

    ``stamp_ns`` is integer nanoseconds since the Unix epoch (integer so that conversions to
    ROS ``sec``/``nanosec`` are exact); :attr:`stamp` gives it as float seconds.
    """

    stamp_ns: int = field(factory=_now_ns, metadata=wire("int (ns since the Unix epoch)"))
    frame_id: str = field(default="", validator=_is_str)

    @stamp_ns.validator
    def _check_stamp(self, _: attrs.Attribute[int], value: int) -> None:
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
            raise TypeValidationError(f"field 'stamp_ns': expected a non-negative int, got {value!r}")

    @property
    def stamp(self) -> float:
        """The stamp in float seconds since the epoch."""
        return self.stamp_ns / 1e9


# -- text -------------------------------------------------------------------------------------


@_named
@define(eq=False)
class StreamingStringMsg(_Message):
    """A chunk of streamed text: ``stream`` is True while chunks flow, ``done`` on the last one."""

    data: str = field(validator=_is_str)
    stream: bool = field(default=False, validator=_is_bool)
    done: bool = field(default=True, validator=_is_bool)
    header: Header = _header_field()


# -- images, audio, video ---------------------------------------------------------------------


def image_array(value: Any, name: str = "data") -> npt.NDArray[Any]:
    """Pixels as a numpy array: an array as is, an array-like (nested lists, as a model server's JSON
    reply gives them) converted, integers from 0 to 255 as uint8, other numbers as their numpy dtype."""
    if isinstance(value, np.ndarray):
        return value
    if not isinstance(value, list | tuple):
        raise TypeValidationError(f"field {name!r}: expected a numpy array or nested lists, got {type(value).__name__}")
    arr = as_numeric_array(value, None, name)
    if arr.dtype.kind in "iub":
        return as_numeric_array(arr, np.uint8, name)
    return arr


def _image_data(value: Any) -> npt.NDArray[Any]:
    value = image_array(value)
    array: npt.NDArray[Any] = value[:, :, np.newaxis] if value.ndim == 2 else value
    if array.ndim != 3:
        raise TypeValidationError(f"field 'data': expected an HxWxC array, got shape {array.shape}")
    height, width = array.shape[:2]
    if height > MAX_IMAGE_SIDE or width > MAX_IMAGE_SIDE:
        raise TypeValidationError(
            f"field 'data': a {height}x{width} image exceeds MAX_IMAGE_SIDE ({MAX_IMAGE_SIDE} pixels a side)"
        )
    _check_holds(array, "data")
    return array


@_named
@define(eq=False)
class ImageMsg(_Message):
    """An image: an HxWxC numpy array with an encoding from :data:`IMAGE_ENCODINGS`."""

    data: npt.NDArray[Any] = field(converter=_image_data,
                                   metadata=wire("HxWxC (|u1; <u2 for mono16 and 16UC1; <f4 for 32FC1)"))
    encoding: str = field(default="rgb8", metadata=wire("str (rgb8, bgr8, rgba8, bgra8, mono8, mono16, 16UC1, 32FC1)"))
    header: Header = _header_field()

    def __attrs_post_init__(self) -> None:
        spec = IMAGE_ENCODINGS.get(self.encoding)
        if spec is None:
            raise TypeValidationError(
                f"field 'encoding': {self.encoding!r} is not supported; use one of {sorted(IMAGE_ENCODINGS)}"
            )
        dtype, channels = spec
        if self.data.dtype != dtype or self.data.shape[2] != channels:
            raise TypeValidationError(
                f"field 'data': encoding {self.encoding!r} needs {dtype.__name__} with {channels} "
                f"channel(s), got {self.data.dtype} with shape {self.data.shape}"
            )

    @property
    def height(self) -> int:
        return int(self.data.shape[0])

    @property
    def width(self) -> int:
        return int(self.data.shape[1])

    def to_rgb(self) -> npt.NDArray[Any]:
        """The pixels as HxWx3 RGB (a view where possible); mono and depth stay single-channel."""
        if self.encoding in ("bgr8", "bgra8"):
            return self.data[:, :, 2::-1]
        if self.encoding == "rgba8":
            return self.data[:, :, :3]
        return self.data

    @classmethod
    def from_array(cls, array: Any, header: Header | None = None) -> ImageMsg:
        """Wrap an array (or nested lists: integers 0-255 as uint8), guessing the encoding from dtype and
        channels (rgb8, rgba8, mono8, 16UC1, 32FC1)."""
        array = image_array(array)
        channels = 1 if array.ndim == 2 else (array.shape[2] if array.ndim == 3 else -1)
        guesses = {(np.dtype(np.uint8), 3): "rgb8", (np.dtype(np.uint8), 4): "rgba8",
                   (np.dtype(np.uint8), 1): "mono8", (np.dtype(np.uint16), 1): "16UC1",
                   (np.dtype(np.float32), 1): "32FC1"}
        encoding = guesses.get((array.dtype, channels))
        if encoding is None:
            raise TypeValidationError(
                f"cannot guess an image encoding for dtype {array.dtype} and shape {array.shape}; "
                "pass an ImageMsg with an explicit encoding"
            )
        return cls(data=array, encoding=encoding, header=header or Header())


@_named
@define(eq=False)
class CompressedImageMsg(_Message):
    """An encoded image (``format`` such as ``"jpeg"`` or ``"png"``) kept as bytes."""

    data: bytes = field(validator=_instance_of(bytes))
    format: str = field(default="jpeg", validator=_is_str, metadata=wire("str (jpeg, png, ...)"))
    header: Header = _header_field()


def _pcm(value: Any) -> npt.NDArray[Any]:
    if isinstance(value, bytes | bytearray):
        value = np.frombuffer(bytes(value), dtype=np.int16)
    if not isinstance(value, np.ndarray) or value.dtype not in (np.int16, np.float32):
        raise TypeValidationError("field 'data': expected PCM as a numpy int16 or float32 array (or int16 bytes)")
    if value.ndim != 1:
        raise TypeValidationError(f"field 'data': expected interleaved 1-D samples, got shape {value.shape}")
    _check_holds(value, "data")
    return value


@_named
@define(eq=False)
class AudioMsg(_Message):
    """PCM audio: interleaved int16 or float32 samples at ``sample_rate`` Hz."""

    data: npt.NDArray[Any] = field(converter=_pcm, metadata=wire("1-D interleaved samples (<i2 or <f4)"))
    sample_rate: int = field(default=16000, metadata=wire("int (Hz)"))
    channels: int = field(default=1)
    header: Header = _header_field()

    def __attrs_post_init__(self) -> None:
        # The bounds are ROS 2's field types (uint32 sample_rate, uint16 channels in agents_interfaces/Audio).
        for name, most in (("sample_rate", 2**32 - 1), ("channels", 2**16 - 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not 0 < value <= most:
                raise TypeValidationError(f"field {name!r}: expected an int from 1 to {most}, got {value!r}")
        if self.data.size % self.channels:
            raise TypeValidationError(
                f"field 'data': {self.data.size} samples do not divide into {self.channels} channels"
            )

    @property
    def duration(self) -> float:
        """Length in seconds."""
        return self.data.size / self.channels / self.sample_rate


def _frames(value: Any) -> list[ImageMsg | CompressedImageMsg]:
    frames = list(value)
    for i, frame in enumerate(frames):
        if not isinstance(frame, ImageMsg | CompressedImageMsg):
            raise TypeValidationError(f"field 'frames[{i}]': expected ImageMsg or CompressedImageMsg")
    return frames


@_named
@define(eq=False)
class VideoMsg(_Message):
    """A sequence of frames bundled as one message."""

    frames: list[ImageMsg | CompressedImageMsg] = field(factory=list, converter=_frames)
    header: Header = _header_field()


# -- perception results -----------------------------------------------------------------------


@_named
@define(eq=False)
class DetectionsMsg(_Message):
    """Object detections: ``boxes`` Nx4 (x1, y1, x2, y2 pixels), ``labels`` and ``scores`` of N."""

    boxes: npt.NDArray[np.float32] = field(factory=lambda: np.zeros((0, 4), np.float32),
                                           converter=_boxes, metadata=_BOXES)
    labels: list[str] = field(factory=list, validator=_is_str_list)
    scores: npt.NDArray[np.float32] = field(factory=lambda: np.zeros(0, np.float32),
                                            converter=_scores, metadata=wire("[float, ...]", as_list=True))
    image: ImageMsg | None = field(default=None, validator=_instance_of(ImageMsg, optional=True))
    header: Header = _header_field()

    def __attrs_post_init__(self) -> None:
        n = self.boxes.shape[0]
        if len(self.labels) != n or self.scores.shape[0] != n:
            raise TypeValidationError(
                f"detections: {n} boxes, {len(self.labels)} labels and {self.scores.shape[0]} scores must match"
            )


@_named
@define(eq=False)
class TrackingsMsg(_Message):
    """Tracked objects: 64-bit ``ids`` plus boxes, centroids and estimated velocities per object."""

    ids: npt.NDArray[np.int64] = field(factory=lambda: np.zeros(0, np.int64),
                                       converter=_ids, metadata=wire("[int, ...]", as_list=True))
    labels: list[str] = field(factory=list, validator=_is_str_list)
    boxes: npt.NDArray[np.float32] = field(factory=lambda: np.zeros((0, 4), np.float32),
                                           converter=_boxes, metadata=_BOXES)
    centroids: npt.NDArray[np.float32] = field(factory=lambda: np.zeros((0, 2), np.float32),
                                               converter=_centroids, metadata=wire("[[x, y] float, ...]", as_list=True))
    estimated_velocities: npt.NDArray[np.float32] = field(
        factory=lambda: np.zeros((0, 2), np.float32),
        converter=_estimated_velocities, metadata=wire("[[vx, vy] float, ...]", as_list=True),
    )
    image: ImageMsg | None = field(default=None, validator=_instance_of(ImageMsg, optional=True))
    header: Header = _header_field()

    def __attrs_post_init__(self) -> None:
        n = self.ids.shape[0]
        sizes = {len(self.labels), self.boxes.shape[0], self.centroids.shape[0],
                 self.estimated_velocities.shape[0]}
        if sizes != {n}:
            raise TypeValidationError(f"trackings: ids, labels, boxes, centroids and velocities must all have {n} rows")


@_named
@define(eq=False)
class PointsOfInterestMsg(_Message):
    """Points on an image (Nx2 pixel coordinates), with the image they refer to."""

    points: npt.NDArray[np.float32] = field(factory=lambda: np.zeros((0, 2), np.float32),
                                            converter=_points, metadata=wire("[[x, y] float, ...]", as_list=True))
    image: ImageMsg | None = field(default=None, validator=_instance_of(ImageMsg, optional=True))
    header: Header = _header_field()


# -- geometry and robot state -----------------------------------------------------------------


@_named
@define(eq=False)
class PointMsg(_Message):
    """A 3-D point."""

    x: float = field(default=0.0, validator=_is_number)
    y: float = field(default=0.0, validator=_is_number)
    z: float = field(default=0.0, validator=_is_number)
    header: Header = _header_field()


@_named
@define(eq=False)
class PoseMsg(_Message):
    """A pose: ``position`` (x, y, z) and ``orientation`` as a quaternion (x, y, z, w)."""

    position: npt.NDArray[np.float64] = field(factory=lambda: np.zeros(3),
                                              converter=_position, metadata=wire("[x, y, z] float", as_list=True))
    orientation: npt.NDArray[np.float64] = field(factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]),
                                                 converter=_orientation,
                                                 metadata=wire("[x, y, z, w] float", as_list=True))
    header: Header = _header_field()


@_named
@define(eq=False)
class TwistMsg(_Message):
    """A velocity: ``linear`` and ``angular`` 3-vectors."""

    linear: npt.NDArray[np.float64] = field(factory=lambda: np.zeros(3),
                                            converter=_linear, metadata=wire("[x, y, z] float", as_list=True))
    angular: npt.NDArray[np.float64] = field(factory=lambda: np.zeros(3),
                                             converter=_angular, metadata=wire("[x, y, z] float", as_list=True))
    header: Header = _header_field()


@_named
@define(eq=False)
class OdometryMsg(_Message):
    """Pose and twist of ``child_frame_id`` in ``header.frame_id``."""

    pose: PoseMsg = field(factory=PoseMsg, validator=_instance_of(PoseMsg))
    twist: TwistMsg = field(factory=TwistMsg, validator=_instance_of(TwistMsg))
    child_frame_id: str = field(default="", validator=_is_str)
    header: Header = _header_field()




def _empty_f64() -> npt.NDArray[np.float64]:
    return np.zeros(0)


@_named
@define(eq=False)
class JointStateMsg(_Message):
    """Joint names with positions, velocities and efforts (each empty or one per name)."""

    name: list[str] = field(factory=list, validator=_is_str_list)
    position: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_position_vector, metadata=_FLOATS)
    velocity: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_velocity, metadata=_FLOATS)
    effort: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_effort, metadata=_FLOATS)
    header: Header = _header_field()

    def __attrs_post_init__(self) -> None:
        for fname in ("position", "velocity", "effort"):
            size = getattr(self, fname).shape[0]
            if size not in (0, len(self.name)):
                raise TypeValidationError(f"field {fname!r}: {size} values for {len(self.name)} joints")


@_named
@define(eq=False)
class JointTrajectoryPointMsg(_Message):
    """One waypoint of a joint trajectory; ``time_from_start`` in seconds."""

    positions: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_positions, metadata=_FLOATS)
    velocities: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_velocities, metadata=_FLOATS)
    accelerations: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_accelerations, metadata=_FLOATS)
    effort: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_effort, metadata=_FLOATS)
    time_from_start: float = field(default=0.0, validator=_is_number, metadata=wire("float (s)"))


def _trajectory_points(value: Any) -> list[JointTrajectoryPointMsg]:
    points = list(value)
    for i, p in enumerate(points):
        if not isinstance(p, JointTrajectoryPointMsg):
            raise TypeValidationError(f"field 'points[{i}]': expected JointTrajectoryPointMsg")
    return points


@_named
@define(eq=False)
class JointTrajectoryMsg(_Message):
    """A trajectory: joint names and a list of waypoints."""

    joint_names: list[str] = field(factory=list, validator=_is_str_list)
    points: list[JointTrajectoryPointMsg] = field(factory=list, converter=_trajectory_points)
    header: Header = _header_field()


@_named
@define(eq=False)
class JointJogMsg(_Message):
    """Jog command: per-joint displacements and/or velocities over ``duration`` seconds."""

    joint_names: list[str] = field(factory=list, validator=_is_str_list)
    displacements: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_displacements, metadata=_FLOATS)
    velocities: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_velocities, metadata=_FLOATS)
    duration: float = field(default=0.0, validator=_is_number, metadata=wire("float (s)"))
    header: Header = _header_field()


@_named
@define(eq=False)
class OccupancyGridMsg(_Message):
    """A 2-D grid map: int8 cells (-1 unknown, 0..100 occupancy), ``resolution`` m/cell."""

    data: npt.NDArray[np.int8] = field(factory=lambda: np.zeros((0, 0), np.int8),
                                       converter=_data, metadata=wire("HxW |i1 (-1 unknown, 0..100)"))
    resolution: float = field(default=0.05, validator=_is_number, metadata=wire("float (m/cell)"))
    origin: PoseMsg = field(factory=PoseMsg, validator=_instance_of(PoseMsg))
    header: Header = _header_field()


@_named
@define(eq=False)
class LaserScanMsg(_Message):
    """A planar laser scan (angles in radians, ranges in metres)."""

    angle_min: float = field(default=0.0, validator=_is_number)
    angle_max: float = field(default=0.0, validator=_is_number)
    angle_increment: float = field(default=0.0, validator=_is_number)
    time_increment: float = field(default=0.0, validator=_is_number)
    scan_time: float = field(default=0.0, validator=_is_number)
    range_min: float = field(default=0.0, validator=_is_number)
    range_max: float = field(default=0.0, validator=_is_number)
    ranges: npt.NDArray[np.float32] = field(factory=lambda: np.zeros(0, np.float32),
                                            converter=_ranges, metadata=wire("1-D <f4"))
    intensities: npt.NDArray[np.float32] = field(factory=lambda: np.zeros(0, np.float32),
                                                 converter=_intensities, metadata=wire("1-D <f4"))
    header: Header = _header_field()


# -- depth cameras, point clouds, inertial and satellite sensors --------------------------------

#: Encodings a depth image may have: millimetres as uint16, or metres as float32.
DEPTH_ENCODINGS = ("16UC1", "mono16", "32FC1")


@_named
@define(eq=False)
class RGBDMsg(_Message):
    """An aligned colour image and depth image of the same size (a depth camera's frame).

    It behaves as its colour image where an image is expected (``data``, ``encoding``, ``to_rgb``):
    the RGBD type is accepted wherever Image is.
    """

    image: ImageMsg = field(validator=_instance_of(ImageMsg))
    depth: ImageMsg = field(validator=_instance_of(ImageMsg))
    header: Header = _header_field()

    def __attrs_post_init__(self) -> None:
        if self.depth.encoding not in DEPTH_ENCODINGS:
            raise TypeValidationError(f"field 'depth': encoding {self.depth.encoding!r} is not a depth encoding "
                                      f"(use one of {', '.join(DEPTH_ENCODINGS)})")
        if (self.image.height, self.image.width) != (self.depth.height, self.depth.width):
            raise TypeValidationError(f"field 'depth': {self.depth.height}x{self.depth.width} depth does not match "
                                      f"the {self.image.height}x{self.image.width} image")

    @property
    def data(self) -> npt.NDArray[Any]:
        """The colour image's pixels."""
        return self.image.data

    @property
    def encoding(self) -> str:
        return self.image.encoding

    @property
    def height(self) -> int:
        return self.image.height

    @property
    def width(self) -> int:
        return self.image.width

    def to_rgb(self) -> npt.NDArray[Any]:
        """The colour image as HxWx3 RGB (see :meth:`ImageMsg.to_rgb`)."""
        return self.image.to_rgb()


#: The numpy dtypes a point field may have: those of ``sensor_msgs/PointField`` (INT8 .. FLOAT64).
POINT_FIELD_DTYPES = ("i1", "u1", "i2", "u2", "i4", "u4", "f4", "f8")


def _cloud_points(value: Any) -> npt.NDArray[Any]:
    if not isinstance(value, np.ndarray) or value.dtype.fields is None:
        raise TypeValidationError(
            "field 'points': expected a numpy structured array with float fields x, y, z (e.g. "
            "np.zeros(n, dtype=[('x', '<f4'), ('y', '<f4'), ('z', '<f4')])), got "
            f"{type(value).__name__}{'' if not isinstance(value, np.ndarray) else ' of dtype ' + str(value.dtype)}"
        )
    fields = value.dtype.fields
    for axis in ("x", "y", "z"):
        if axis not in fields or fields[axis][0].kind != "f":
            raise TypeValidationError(f"field 'points': needs a float field {axis!r} (has {list(fields)})")
    for name, (dtype, _offset, *_) in fields.items():
        if dtype.shape or f"{dtype.kind}{dtype.itemsize}" not in POINT_FIELD_DTYPES or dtype.byteorder == ">":
            raise TypeValidationError(f"field 'points': point field {name!r} has dtype {dtype}; a point field is "
                                      f"one little-endian {'/'.join(POINT_FIELD_DTYPES)} number")
    if value.ndim == 2 and value.shape[0] == 1:
        value = value[0]  # one row: an unorganised cloud (what ROS calls height 1)
    if value.ndim not in (1, 2):
        raise TypeValidationError(f"field 'points': expected N points or an HxW organised cloud, got shape "
                                  f"{value.shape}")
    points: npt.NDArray[Any] = value
    _check_holds(points, "points")
    return points


@_named
@define(eq=False)
class PointCloud2Msg(_Message):
    """A point cloud: a numpy structured array with float fields ``x``, ``y``, ``z`` and any others
    (``rgb``, ``intensity``, ...), N points or HxW (an organised cloud); ``is_dense`` when no point is invalid."""

    points: npt.NDArray[Any] = field(converter=_cloud_points, metadata=wire(structured=True))
    is_dense: bool = field(default=True, validator=_is_bool)
    header: Header = _header_field()

    @property
    def xyz(self) -> npt.NDArray[Any]:
        """The coordinates as an Nx3 float array (a copy)."""
        flat = self.points.reshape(-1)
        xyz: npt.NDArray[Any] = np.stack([flat["x"], flat["y"], flat["z"]], axis=-1)
        return xyz


def _covariance_9(value: Any, name: str) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (9,), name)


def _orientation_covariance(value: Any) -> npt.NDArray[np.float64]:
    return _covariance_9(value, "orientation_covariance")


def _angular_velocity_covariance(value: Any) -> npt.NDArray[np.float64]:
    return _covariance_9(value, "angular_velocity_covariance")


def _linear_acceleration_covariance(value: Any) -> npt.NDArray[np.float64]:
    return _covariance_9(value, "linear_acceleration_covariance")


def _position_covariance(value: Any) -> npt.NDArray[np.float64]:
    return _covariance_9(value, "position_covariance")


def _angular_velocity(value: Any) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (3,), "angular_velocity")


def _linear_acceleration(value: Any) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (3,), "linear_acceleration")


def _zeros_9() -> npt.NDArray[np.float64]:
    return np.zeros(9)


_COVARIANCE = wire("[float x 9] (row-major 3x3)", as_list=True)
_VECTOR3 = wire("[x, y, z] float", as_list=True)


@_named
@define(eq=False)
class ImuMsg(_Message):
    """An inertial measurement: orientation (quaternion x, y, z, w), angular velocity (rad/s) and linear
    acceleration (m/s²), each with a row-major 3x3 covariance (9 values; element 0 of -1: not estimated)."""

    orientation: npt.NDArray[np.float64] = field(factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]),
                                                 converter=_orientation,
                                                 metadata=wire("[x, y, z, w] float", as_list=True))
    orientation_covariance: npt.NDArray[np.float64] = field(factory=_zeros_9, converter=_orientation_covariance,
                                                            metadata=_COVARIANCE)
    angular_velocity: npt.NDArray[np.float64] = field(factory=lambda: np.zeros(3), converter=_angular_velocity,
                                                      metadata=_VECTOR3)
    angular_velocity_covariance: npt.NDArray[np.float64] = field(factory=_zeros_9,
                                                                 converter=_angular_velocity_covariance,
                                                                 metadata=_COVARIANCE)
    linear_acceleration: npt.NDArray[np.float64] = field(factory=lambda: np.zeros(3), converter=_linear_acceleration,
                                                         metadata=_VECTOR3)
    linear_acceleration_covariance: npt.NDArray[np.float64] = field(factory=_zeros_9,
                                                                    converter=_linear_acceleration_covariance,
                                                                    metadata=_COVARIANCE)
    header: Header = _header_field()


def _int_in(low: int, high: int) -> Callable[[Any, attrs.Attribute[Any], Any], None]:
    def check(_: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or not low <= int(value) <= high:
            raise TypeValidationError(f"field {attribute.name!r}: expected an int from {low} to {high}, got {value!r}")

    return check


@_named
@define(eq=False)
class NavSatFixMsg(_Message):
    """A satellite fix: latitude and longitude (degrees), altitude (m), the fix ``status`` (-1 no fix, 0 fix,
    1 SBAS, 2 GBAS), the ``service`` bits (1 GPS, 2 GLONASS, 4 COMPASS, 8 GALILEO) and an ENU covariance (m²)."""

    latitude: float = field(default=0.0, validator=_is_number)
    longitude: float = field(default=0.0, validator=_is_number)
    altitude: float = field(default=0.0, validator=_is_number)
    status: int = field(default=-1, validator=_int_in(-1, 2), metadata=wire("int (-1 no fix, 0 fix, 1 SBAS, 2 GBAS)"))
    service: int = field(default=1, validator=_int_in(0, 2**16 - 1), metadata=wire("int (bits: 1 GPS, 2 GLONASS, ...)"))
    position_covariance: npt.NDArray[np.float64] = field(factory=_zeros_9, converter=_position_covariance,
                                                         metadata=_COVARIANCE)
    position_covariance_type: int = field(default=0, validator=_int_in(0, 3),
                                          metadata=wire("int (0 unknown, 1 approximated, 2 diagonal, 3 known)"))
    header: Header = _header_field()


def _poses(value: Any) -> list[PoseMsg]:
    if not isinstance(value, list | tuple):
        raise TypeValidationError(f"field 'poses': expected a list of PoseMsg, got {type(value).__name__}")
    poses = list(value)
    for i, pose in enumerate(poses):
        if not isinstance(pose, PoseMsg):
            raise TypeValidationError(f"field 'poses[{i}]': expected PoseMsg, got {type(pose).__name__}")
    return poses


@_named
@define(eq=False)
class PathMsg(_Message):
    """A path: a list of poses, each with its own header (stamp and frame), as ``nav_msgs/Path``."""

    poses: list[PoseMsg] = field(factory=list, converter=_poses)
    header: Header = _header_field()


@_named
@define(eq=False)
class PoseArrayMsg(_Message):
    """Poses in one frame (``header``), as ``geometry_msgs/PoseArray``; the poses' own headers are not sent
    on ROS 2 (they arrive as the array's)."""

    poses: list[PoseMsg] = field(factory=list, converter=_poses)
    header: Header = _header_field()


@_named
@define(eq=False)
class MapMetaDataMsg(_Message):
    """A grid map's geometry: ``resolution`` (m/cell), ``width`` x ``height`` cells, the ``origin`` pose of
    cell (0, 0), and when the map was loaded (``map_load_time_ns``, ns since the epoch)."""

    resolution: float = field(default=0.05, validator=_is_number, metadata=wire("float (m/cell)"))
    width: int = field(default=0, validator=_int_in(0, 2**32 - 1))
    height: int = field(default=0, validator=_int_in(0, 2**32 - 1))
    origin: PoseMsg = field(factory=PoseMsg, validator=_instance_of(PoseMsg))
    map_load_time_ns: int = field(default=0, validator=_int_in(0, 2**63 - 1),
                                  metadata=wire("int (ns since the Unix epoch)"))


def _d(value: Any) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (None,), "d")


def _k(value: Any) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (9,), "k")


def _r(value: Any) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (9,), "r")


def _p(value: Any) -> npt.NDArray[np.float64]:
    return _to_array(value, np.float64, (12,), "p")


def _roi(value: Any) -> npt.NDArray[np.int64]:
    roi = _to_array(value, np.int64, (4,), "roi")
    if roi.size and (roi.min() < 0 or roi.max() > 2**32 - 1):
        raise TypeValidationError(f"field 'roi': values must be uint32, got {roi.tolist()}")
    return roi


@_named
@define(eq=False)
class CameraInfoMsg(_Message):
    """A camera's calibration, as ``sensor_msgs/CameraInfo``: image size, distortion model and
    coefficients ``d``, intrinsics ``k`` (3x3), rectification ``r`` (3x3), projection ``p`` (3x4), all
    row-major; binning; region of interest (x_offset, y_offset, height, width) and whether to rectify it."""

    height: int = field(default=0, validator=_int_in(0, 2**32 - 1))
    width: int = field(default=0, validator=_int_in(0, 2**32 - 1))
    distortion_model: str = field(default="plumb_bob", validator=_is_str,
                                  metadata=wire("str (plumb_bob, rational_polynomial, equidistant, ...)"))
    d: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_d, metadata=_FLOATS)
    k: npt.NDArray[np.float64] = field(factory=_zeros_9, converter=_k, metadata=wire("[float x 9] (3x3)",
                                                                                      as_list=True))
    r: npt.NDArray[np.float64] = field(factory=_zeros_9, converter=_r, metadata=wire("[float x 9] (3x3)",
                                                                                      as_list=True))
    p: npt.NDArray[np.float64] = field(factory=lambda: np.zeros(12), converter=_p,
                                       metadata=wire("[float x 12] (3x4)", as_list=True))
    binning_x: int = field(default=0, validator=_int_in(0, 2**32 - 1))
    binning_y: int = field(default=0, validator=_int_in(0, 2**32 - 1))
    roi: npt.NDArray[np.int64] = field(factory=lambda: np.zeros(4, np.int64), converter=_roi,
                                       metadata=wire("[x_offset, y_offset, height, width] int", as_list=True))
    roi_do_rectify: bool = field(default=False, validator=_is_bool)
    header: Header = _header_field()


# -- framework status -------------------------------------------------------------------------


@_named
@define(eq=False)
class ComponentStatusMsg(_Message):
    """A component's lifecycle state and health, as published on its status topic.

    ``health`` is one of the :class:`~agents_core.status.HealthStatus` names
    (``"HEALTHY"``, ``"ALGORITHM_FAILURE"``, ``"COMPONENT_FAILURE"``, ``"SYSTEM_FAILURE"``).
    """

    component: str = field(validator=_is_str)
    lifecycle_state: str = field(default="unconfigured", validator=_is_str)
    health: str = field(default="HEALTHY", validator=_is_str, metadata=wire("str (HEALTHY, ALGORITHM_FAILURE, ...)"))
    message: str = field(default="", validator=_is_str)
    header: Header = _header_field()
