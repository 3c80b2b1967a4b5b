"""Value classes: the plain Python form of every message that flows between components.

Simple types travel as builtins (``str``, ``bool``, ``int``, ``float``) or numpy arrays. Structured
types are small attrs classes defined here, each with a :class:`Header` (stamp and frame_id)
that transport conversions preserve end to end. Constructing a value validates it and raises
:class:`~agents_core.errors.TypeValidationError` naming the field that is wrong.

Values are delivered zero-copy on the memory transport: every subscriber receives the same
object, so treat received values (and their numpy arrays) as read-only.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import attrs
import numpy as np
import numpy.typing as npt
from attrs import define, field

from .errors import TypeValidationError

__all__ = [
    "IMAGE_ENCODINGS",
    "MAX_ARRAY_DIM",
    "MAX_IMAGE_SIDE",
    "AudioMsg",
    "ComponentStatusMsg",
    "CompressedImageMsg",
    "DetectionsMsg",
    "Header",
    "ImageMsg",
    "JointJogMsg",
    "JointStateMsg",
    "JointTrajectoryMsg",
    "JointTrajectoryPointMsg",
    "LaserScanMsg",
    "OccupancyGridMsg",
    "OdometryMsg",
    "PointMsg",
    "PointsOfInterestMsg",
    "PoseMsg",
    "StreamingStringMsg",
    "TrackingsMsg",
    "TwistMsg",
    "VideoMsg",
    "values_equal",
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


def _to_array(value: Any, dtype: type[np.generic], shape: tuple[int | None, ...], name: str) -> npt.NDArray[Any]:
    """``value`` as a numpy array of ``dtype`` whose shape matches ``shape`` (None = any size)."""
    try:
        arr = np.asarray(value)
        _check_holds(arr, name)  # before an empty array is reshaped: its claimed dimensions count too
        if arr.size == 0:
            arr = arr.reshape(tuple(0 if d is None else d for d in shape))
        if arr.dtype != dtype:
            if arr.dtype.kind not in "biuf":
                raise TypeError(f"dtype {arr.dtype} is not numeric")
            arr = arr.astype(dtype)
    except TypeValidationError:
        raise
    except (TypeError, ValueError) as exc:
        raise TypeValidationError(f"field {name!r}: cannot make a {dtype.__name__} array: {exc}") from exc
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


def _now_ns() -> int:
    return time.time_ns()


def _header_field() -> Any:
    return field(factory=Header, validator=_instance_of(Header))


# -- header -----------------------------------------------------------------------------------


@define(eq=False)
class Header(_Message):
    """When and in which coordinate frame a value was produced.

    ``stamp_ns`` is integer nanoseconds since the Unix epoch (integer so that conversions to
    ROS ``sec``/``nanosec`` are exact); :attr:`stamp` gives it as float seconds.
    """

    stamp_ns: int = field(factory=_now_ns)
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


@define(eq=False)
class StreamingStringMsg(_Message):
    """A chunk of streamed text: ``stream`` is True while chunks flow, ``done`` on the last one."""

    data: str = field(validator=_is_str)
    stream: bool = field(default=False, validator=_is_bool)
    done: bool = field(default=True, validator=_is_bool)
    header: Header = _header_field()


# -- images, audio, video ---------------------------------------------------------------------


def _image_data(value: Any) -> npt.NDArray[Any]:
    if not isinstance(value, np.ndarray):
        raise TypeValidationError(f"field 'data': expected a numpy array, got {type(value).__name__}")
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


@define(eq=False)
class ImageMsg(_Message):
    """An image: an HxWxC numpy array with an encoding from :data:`IMAGE_ENCODINGS`."""

    data: npt.NDArray[Any] = field(converter=_image_data)
    encoding: str = field(default="rgb8")
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
    def from_array(cls, array: npt.NDArray[Any], header: Header | None = None) -> ImageMsg:
        """Wrap an array, guessing the encoding from dtype and channels (rgb8, rgba8, mono8, 16UC1)."""
        if not isinstance(array, np.ndarray):
            raise TypeValidationError(f"expected a numpy array for an image, got {type(array).__name__}")
        channels = 1 if array.ndim == 2 else (array.shape[2] if array.ndim == 3 else -1)
        guesses = {(np.dtype(np.uint8), 3): "rgb8", (np.dtype(np.uint8), 4): "rgba8",
                   (np.dtype(np.uint8), 1): "mono8", (np.dtype(np.uint16), 1): "16UC1"}
        encoding = guesses.get((array.dtype, channels))
        if encoding is None:
            raise TypeValidationError(
                f"cannot guess an image encoding for dtype {array.dtype} and shape {array.shape}; "
                "pass an ImageMsg with an explicit encoding"
            )
        return cls(data=array, encoding=encoding, header=header or Header())


@define(eq=False)
class CompressedImageMsg(_Message):
    """An encoded image (``format`` such as ``"jpeg"`` or ``"png"``) kept as bytes."""

    data: bytes = field(validator=_instance_of(bytes))
    format: str = field(default="jpeg", validator=_is_str)
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


@define(eq=False)
class AudioMsg(_Message):
    """PCM audio: interleaved int16 or float32 samples at ``sample_rate`` Hz."""

    data: npt.NDArray[Any] = field(converter=_pcm)
    sample_rate: int = field(default=16000)
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


@define(eq=False)
class VideoMsg(_Message):
    """A sequence of frames bundled as one message."""

    frames: list[ImageMsg | CompressedImageMsg] = field(factory=list, converter=_frames)
    header: Header = _header_field()


# -- perception results -----------------------------------------------------------------------


@define(eq=False)
class DetectionsMsg(_Message):
    """Object detections: ``boxes`` Nx4 (x1, y1, x2, y2 pixels), ``labels`` and ``scores`` of N."""

    boxes: npt.NDArray[np.float32] = field(factory=lambda: np.zeros((0, 4), np.float32),
                                           converter=_boxes)
    labels: list[str] = field(factory=list, validator=_is_str_list)
    scores: npt.NDArray[np.float32] = field(factory=lambda: np.zeros(0, np.float32),
                                            converter=_scores)
    image: ImageMsg | None = field(default=None, validator=_instance_of(ImageMsg, optional=True))
    header: Header = _header_field()

    def __attrs_post_init__(self) -> None:
        n = self.boxes.shape[0]
        if len(self.labels) != n or self.scores.shape[0] != n:
            raise TypeValidationError(
                f"detections: {n} boxes, {len(self.labels)} labels and {self.scores.shape[0]} scores must match"
            )


@define(eq=False)
class TrackingsMsg(_Message):
    """Tracked objects: 64-bit ``ids`` plus boxes, centroids and estimated velocities per object."""

    ids: npt.NDArray[np.int64] = field(factory=lambda: np.zeros(0, np.int64),
                                       converter=_ids)
    labels: list[str] = field(factory=list, validator=_is_str_list)
    boxes: npt.NDArray[np.float32] = field(factory=lambda: np.zeros((0, 4), np.float32),
                                           converter=_boxes)
    centroids: npt.NDArray[np.float32] = field(factory=lambda: np.zeros((0, 2), np.float32),
                                               converter=_centroids)
    estimated_velocities: npt.NDArray[np.float32] = field(
        factory=lambda: np.zeros((0, 2), np.float32),
        converter=_estimated_velocities,
    )
    image: ImageMsg | None = field(default=None, validator=_instance_of(ImageMsg, optional=True))
    header: Header = _header_field()

    def __attrs_post_init__(self) -> None:
        n = self.ids.shape[0]
        sizes = {len(self.labels), self.boxes.shape[0], self.centroids.shape[0],
                 self.estimated_velocities.shape[0]}
        if sizes != {n}:
            raise TypeValidationError(f"trackings: ids, labels, boxes, centroids and velocities must all have {n} rows")


@define(eq=False)
class PointsOfInterestMsg(_Message):
    """Points on an image (Nx2 pixel coordinates), with the image they refer to."""

    points: npt.NDArray[np.float32] = field(factory=lambda: np.zeros((0, 2), np.float32),
                                            converter=_points)
    image: ImageMsg | None = field(default=None, validator=_instance_of(ImageMsg, optional=True))
    header: Header = _header_field()


# -- geometry and robot state -----------------------------------------------------------------


@define(eq=False)
class PointMsg(_Message):
    """A 3-D point."""

    x: float = field(default=0.0, validator=_is_number)
    y: float = field(default=0.0, validator=_is_number)
    z: float = field(default=0.0, validator=_is_number)
    header: Header = _header_field()


@define(eq=False)
class PoseMsg(_Message):
    """A pose: ``position`` (x, y, z) and ``orientation`` as a quaternion (x, y, z, w)."""

    position: npt.NDArray[np.float64] = field(factory=lambda: np.zeros(3),
                                              converter=_position)
    orientation: npt.NDArray[np.float64] = field(factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]),
                                                 converter=_orientation)
    header: Header = _header_field()


@define(eq=False)
class TwistMsg(_Message):
    """A velocity: ``linear`` and ``angular`` 3-vectors."""

    linear: npt.NDArray[np.float64] = field(factory=lambda: np.zeros(3),
                                            converter=_linear)
    angular: npt.NDArray[np.float64] = field(factory=lambda: np.zeros(3),
                                             converter=_angular)
    header: Header = _header_field()


@define(eq=False)
class OdometryMsg(_Message):
    """Pose and twist of ``child_frame_id`` in ``header.frame_id``."""

    pose: PoseMsg = field(factory=PoseMsg, validator=_instance_of(PoseMsg))
    twist: TwistMsg = field(factory=TwistMsg, validator=_instance_of(TwistMsg))
    child_frame_id: str = field(default="", validator=_is_str)
    header: Header = _header_field()


def _empty_f64() -> npt.NDArray[np.float64]:
    return np.zeros(0)


@define(eq=False)
class JointStateMsg(_Message):
    """Joint names with positions, velocities and efforts (each empty or one per name)."""

    name: list[str] = field(factory=list, validator=_is_str_list)
    position: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_position_vector)
    velocity: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_velocity)
    effort: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_effort)
    header: Header = _header_field()

    def __attrs_post_init__(self) -> None:
        for fname in ("position", "velocity", "effort"):
            size = getattr(self, fname).shape[0]
            if size not in (0, len(self.name)):
                raise TypeValidationError(f"field {fname!r}: {size} values for {len(self.name)} joints")


@define(eq=False)
class JointTrajectoryPointMsg(_Message):
    """One waypoint of a joint trajectory; ``time_from_start`` in seconds."""

    positions: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_positions)
    velocities: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_velocities)
    accelerations: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_accelerations)
    effort: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_effort)
    time_from_start: float = field(default=0.0, validator=_is_number)


def _trajectory_points(value: Any) -> list[JointTrajectoryPointMsg]:
    points = list(value)
    for i, p in enumerate(points):
        if not isinstance(p, JointTrajectoryPointMsg):
            raise TypeValidationError(f"field 'points[{i}]': expected JointTrajectoryPointMsg")
    return points


@define(eq=False)
class JointTrajectoryMsg(_Message):
    """A trajectory: joint names and a list of waypoints."""

    joint_names: list[str] = field(factory=list, validator=_is_str_list)
    points: list[JointTrajectoryPointMsg] = field(factory=list, converter=_trajectory_points)
    header: Header = _header_field()


@define(eq=False)
class JointJogMsg(_Message):
    """Jog command: per-joint displacements and/or velocities over ``duration`` seconds."""

    joint_names: list[str] = field(factory=list, validator=_is_str_list)
    displacements: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_displacements)
    velocities: npt.NDArray[np.float64] = field(factory=_empty_f64, converter=_velocities)
    duration: float = field(default=0.0, validator=_is_number)
    header: Header = _header_field()


@define(eq=False)
class OccupancyGridMsg(_Message):
    """A 2-D grid map: int8 cells (-1 unknown, 0..100 occupancy), ``resolution`` m/cell."""

    data: npt.NDArray[np.int8] = field(factory=lambda: np.zeros((0, 0), np.int8),
                                       converter=_data)
    resolution: float = field(default=0.05, validator=_is_number)
    origin: PoseMsg = field(factory=PoseMsg, validator=_instance_of(PoseMsg))
    header: Header = _header_field()


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
                                            converter=_ranges)
    intensities: npt.NDArray[np.float32] = field(factory=lambda: np.zeros(0, np.float32),
                                                 converter=_intensities)
    header: Header = _header_field()


# -- framework status -------------------------------------------------------------------------


@define(eq=False)
class ComponentStatusMsg(_Message):
    """A component's lifecycle state and health, as published on its status topic.

    ``health`` is one of the :class:`~agents_core.status.HealthStatus` names
    (``"HEALTHY"``, ``"ALGORITHM_FAILURE"``, ``"COMPONENT_FAILURE"``, ``"SYSTEM_FAILURE"``).
    """

    component: str = field(validator=_is_str)
    lifecycle_state: str = field(default="unconfigured", validator=_is_str)
    health: str = field(default="HEALTHY", validator=_is_str)
    message: str = field(default="", validator=_is_str)
    header: Header = _header_field()
