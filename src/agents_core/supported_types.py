"""The message type registry: ``SupportedType`` and the built-in types.

A :class:`SupportedType` subclass is a *type token*: it is what ``Topic(msg_type=...)`` names and
what ``allowed_inputs`` lists. It is never instantiated. It says which Python values it accepts
(:meth:`SupportedType.validate`, which also normalises convenient forms such as a bare numpy
array for an Image) and what a component's callback hands to ``_execution_step``
(:meth:`SupportedType.to_output`). Transport adapters keep their own codec per type name.

Types are looked up by name through the registry; :func:`add_additional_datatypes` registers
user-defined ones so that ``Topic(msg_type="MyType")`` resolves everywhere.
"""

from __future__ import annotations

import difflib
import math
import threading
from collections.abc import Iterable, Sequence
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from . import messages as m
from .errors import ConfigError, TypeValidationError, UnknownTypeError

__all__ = [
    "Audio",
    "Bool",
    "ComponentStatus",
    "CompressedImage",
    "Detections",
    "DetectionsMultiSource",
    "Float32",
    "Float32MultiArray",
    "Float64",
    "Float64MultiArray",
    "Image",
    "Int32",
    "Int64",
    "JointJog",
    "JointState",
    "JointTrajectory",
    "JointTrajectoryPoint",
    "LaserScan",
    "OccupancyGrid",
    "Odometry",
    "Point",
    "PointStamped",
    "PointsOfInterest",
    "Pose",
    "PoseStamped",
    "StreamingString",
    "String",
    "SupportedType",
    "Trackings",
    "TrackingsMultiSource",
    "Twist",
    "Video",
    "add_additional_datatypes",
    "get_type",
    "registered_types",
]


class SupportedType:
    """Base of every message type token.

    Subclasses set :attr:`value_class` (the Python class of a validated value) and override
    :meth:`validate` when they accept more than instances of it. Subclassing an existing type
    makes the new one acceptable wherever the parent is allowed (``StreamingString`` passes where
    ``String`` is required).
    """

    value_class: ClassVar[type[Any]] = object

    @classmethod
    def type_name(cls) -> str:
        """The registry name (the class name)."""
        return cls.__name__

    @classmethod
    def validate(cls, value: Any) -> Any:
        """Return ``value`` in this type's canonical form, or raise :class:`TypeValidationError`."""
        if isinstance(value, cls.value_class):
            return value
        raise TypeValidationError(
            f"{cls.type_name()} expects {cls.value_class.__name__}, got {type(value).__name__}"
        )

    @classmethod
    def to_output(cls, value: Any) -> Any:
        """What a callback's ``get_output()`` returns for a received value (default: the value)."""
        return value

    @classmethod
    def example(cls) -> Any:
        """A small valid value, used for warm-ups and by the transport conformance tests."""
        raise NotImplementedError(f"{cls.type_name()} has no example value")


def _unstamped() -> m.Header:
    """The header of a value whose standard wire form has none (e.g. geometry_msgs/Pose): stamp 0.

    Transports that cannot carry such a header deliver this one, so examples use it to round-trip.
    """
    return m.Header(stamp_ns=0)


# -- scalars and text -------------------------------------------------------------------------


class String(SupportedType):
    """Text, as ``str``."""

    value_class: ClassVar[type[Any]] = str

    @classmethod
    def example(cls) -> Any:
        return "hello robot"


class StreamingString(String):
    """Streamed text chunks (:class:`~agents_core.messages.StreamingStringMsg`); a ``str`` is one final chunk."""

    value_class = m.StreamingStringMsg

    @classmethod
    def validate(cls, value: Any) -> Any:
        if isinstance(value, str):
            return m.StreamingStringMsg(data=value)
        return super().validate(value)

    @classmethod
    def to_output(cls, value: Any) -> Any:
        return value.data

    @classmethod
    def example(cls) -> Any:
        return m.StreamingStringMsg(data="partial", stream=True, done=False)


class Bool(SupportedType):
    """A boolean."""

    value_class = bool

    @classmethod
    def validate(cls, value: Any) -> Any:
        if isinstance(value, bool | np.bool_):
            return bool(value)
        raise TypeValidationError(f"Bool expects bool, got {type(value).__name__}")

    @classmethod
    def example(cls) -> Any:
        return True


def _integer(name: str, value: Any, bits: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise TypeValidationError(f"{name} expects int, got {type(value).__name__}")
    if not -(2 ** (bits - 1)) <= int(value) < 2 ** (bits - 1):
        raise TypeValidationError(f"{name} value {value} does not fit in {bits} bits")
    return int(value)


def _real(name: str, value: Any, single: bool) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise TypeValidationError(f"{name} expects a number, got {type(value).__name__}")
    if single and math.isfinite(float(value)) and abs(float(value)) > float(np.finfo(np.float32).max):
        raise TypeValidationError(f"{name} value {value} overflows float32")
    return float(value)


class Int32(SupportedType):
    """A 32-bit signed integer, as ``int``."""

    value_class = int

    @classmethod
    def validate(cls, value: Any) -> Any:
        return _integer(cls.type_name(), value, 32)

    @classmethod
    def example(cls) -> Any:
        return -42


class Int64(Int32):
    """A 64-bit signed integer, as ``int``."""

    @classmethod
    def validate(cls, value: Any) -> Any:
        return _integer(cls.type_name(), value, 64)

    @classmethod
    def example(cls) -> Any:
        return 2**40


class Float32(SupportedType):
    """A single-precision float, as ``float``."""

    value_class = float

    @classmethod
    def validate(cls, value: Any) -> Any:
        return _real(cls.type_name(), value, single=True)

    @classmethod
    def example(cls) -> Any:
        return 0.5


class Float64(Float32):
    """A double-precision float, as ``float``."""

    @classmethod
    def validate(cls, value: Any) -> Any:
        return _real(cls.type_name(), value, single=False)

    @classmethod
    def example(cls) -> Any:
        return 3.141592653589793


class Float32MultiArray(SupportedType):
    """An n-dimensional float32 numpy array."""

    value_class = np.ndarray
    dtype: ClassVar[type[np.generic]] = np.float32

    @classmethod
    def validate(cls, value: Any) -> Any:
        if isinstance(value, np.ndarray) and value.dtype == cls.dtype:
            return value
        if isinstance(value, np.ndarray | Sequence) and not isinstance(value, str | bytes):
            arr: npt.NDArray[Any] = np.asarray(value)
            if arr.dtype.kind in "iuf":
                return arr.astype(cls.dtype)
        raise TypeValidationError(f"{cls.type_name()} expects a numeric array, got {type(value).__name__}")

    @classmethod
    def example(cls) -> Any:
        return np.arange(6, dtype=cls.dtype).reshape(2, 3)


class Float64MultiArray(Float32MultiArray):
    """An n-dimensional float64 numpy array."""

    dtype = np.float64


# -- images, audio, video ---------------------------------------------------------------------


class Image(SupportedType):
    """A raw image (:class:`~agents_core.messages.ImageMsg`); a bare numpy array is wrapped.

    ``get_output()`` gives the pixels as a numpy array, RGB for colour encodings.
    """

    value_class = m.ImageMsg

    @classmethod
    def validate(cls, value: Any) -> Any:
        if isinstance(value, np.ndarray):
            return m.ImageMsg.from_array(value)
        return super().validate(value)

    @classmethod
    def to_output(cls, value: Any) -> Any:
        return value.to_rgb()

    @classmethod
    def example(cls) -> Any:
        pixels = np.arange(4 * 5 * 3, dtype=np.uint8).reshape(4, 5, 3)
        return m.ImageMsg(data=pixels, encoding="rgb8", header=m.Header(stamp_ns=1_700_000_000_123_456_789,
                                                                        frame_id="camera"))


class CompressedImage(SupportedType):
    """An encoded image (:class:`~agents_core.messages.CompressedImageMsg`)."""

    value_class = m.CompressedImageMsg

    @classmethod
    def example(cls) -> Any:
        return m.CompressedImageMsg(data=b"\x89PNG\r\n\x1a\n-not-really", format="png")


class Audio(SupportedType):
    """PCM audio (:class:`~agents_core.messages.AudioMsg`); int16 bytes or a 1-D array are wrapped at 16 kHz."""

    value_class = m.AudioMsg

    @classmethod
    def validate(cls, value: Any) -> Any:
        if isinstance(value, bytes | bytearray | np.ndarray):
            return m.AudioMsg(data=value)
        return super().validate(value)

    @classmethod
    def example(cls) -> Any:
        return m.AudioMsg(data=np.array([0, 1000, -1000, 32767], dtype=np.int16), sample_rate=16000)


class Video(SupportedType):
    """A bundle of frames (:class:`~agents_core.messages.VideoMsg`)."""

    value_class = m.VideoMsg

    @classmethod
    def example(cls) -> Any:
        return m.VideoMsg(frames=[Image.example(), Image.example()])


# -- perception -------------------------------------------------------------------------------


class Detections(SupportedType):
    """Detection results (:class:`~agents_core.messages.DetectionsMsg`)."""

    value_class = m.DetectionsMsg

    @classmethod
    def example(cls) -> Any:
        return m.DetectionsMsg(boxes=[[1, 2, 30, 40], [5, 5, 9, 9]], labels=["cup", "person"],
                               scores=[0.9, 0.5], image=Image.example())


class _ListOf(SupportedType):
    """A list of one value class (the multi-source types)."""

    item: ClassVar[type[SupportedType]] = SupportedType
    value_class = list

    @classmethod
    def validate(cls, value: Any) -> Any:
        if not isinstance(value, list | tuple):
            raise TypeValidationError(f"{cls.type_name()} expects a list, got {type(value).__name__}")
        return [cls.item.validate(v) for v in value]

    @classmethod
    def example(cls) -> Any:
        return [cls.item.example(), cls.item.example()]


class DetectionsMultiSource(_ListOf):
    """Detections from several cameras: a list of DetectionsMsg."""

    item = Detections


class Trackings(SupportedType):
    """Tracked objects (:class:`~agents_core.messages.TrackingsMsg`)."""

    value_class = m.TrackingsMsg

    @classmethod
    def example(cls) -> Any:
        return m.TrackingsMsg(ids=[2**40 + 1], labels=["cup"], boxes=[[1, 2, 3, 4]], centroids=[[2, 3]],
                              estimated_velocities=[[0.1, -0.2]])


class TrackingsMultiSource(_ListOf):
    """Trackings from several cameras: a list of TrackingsMsg."""

    item = Trackings


class PointsOfInterest(SupportedType):
    """Points on an image (:class:`~agents_core.messages.PointsOfInterestMsg`)."""

    value_class = m.PointsOfInterestMsg

    @classmethod
    def example(cls) -> Any:
        return m.PointsOfInterestMsg(points=[[1.5, 2.5], [3, 4]], image=Image.example())


# -- geometry and robot state -----------------------------------------------------------------


class Point(SupportedType):
    """A 3-D point (:class:`~agents_core.messages.PointMsg`)."""

    value_class = m.PointMsg

    @classmethod
    def example(cls) -> Any:
        return m.PointMsg(x=1.0, y=-2.0, z=0.5, header=_unstamped())


class PointStamped(Point):
    """A 3-D point whose header matters (stamp and frame)."""

    @classmethod
    def example(cls) -> Any:
        return m.PointMsg(x=1.0, y=-2.0, z=0.5, header=m.Header(stamp_ns=1_700_000_000_000_000_007, frame_id="map"))


class Pose(SupportedType):
    """A pose (:class:`~agents_core.messages.PoseMsg`)."""

    value_class = m.PoseMsg

    @classmethod
    def example(cls) -> Any:
        return m.PoseMsg(position=[1, 2, 3], orientation=[0, 0, 0.7071068, 0.7071068], header=_unstamped())


class PoseStamped(Pose):
    """A pose whose header matters (stamp and frame)."""

    @classmethod
    def example(cls) -> Any:
        return m.PoseMsg(position=[1, 2, 3], orientation=[0, 0, 0, 1],
                         header=m.Header(stamp_ns=1_700_000_000_000_000_009, frame_id="odom"))


class Twist(SupportedType):
    """A velocity command (:class:`~agents_core.messages.TwistMsg`)."""

    value_class = m.TwistMsg

    @classmethod
    def example(cls) -> Any:
        return m.TwistMsg(linear=[0.2, 0, 0], angular=[0, 0, 0.5], header=_unstamped())


class Odometry(SupportedType):
    """Odometry (:class:`~agents_core.messages.OdometryMsg`)."""

    value_class = m.OdometryMsg

    @classmethod
    def example(cls) -> Any:
        # Pose and twist share the message's header (nav_msgs/Odometry carries one header).
        stamp, frame = 1_700_000_000_000_000_013, "odom"
        pose = m.PoseMsg(position=[1, 2, 0], header=m.Header(stamp_ns=stamp, frame_id=frame))
        twist = m.TwistMsg(linear=[0.2, 0, 0], header=m.Header(stamp_ns=stamp, frame_id=frame))
        return m.OdometryMsg(pose=pose, twist=twist, child_frame_id="base_link",
                             header=m.Header(stamp_ns=stamp, frame_id=frame))


class JointState(SupportedType):
    """Joint states (:class:`~agents_core.messages.JointStateMsg`)."""

    value_class = m.JointStateMsg

    @classmethod
    def example(cls) -> Any:
        return m.JointStateMsg(name=["shoulder", "elbow"], position=[0.1, 0.2], velocity=[0, 0], effort=[])


class JointTrajectoryPoint(SupportedType):
    """One trajectory waypoint (:class:`~agents_core.messages.JointTrajectoryPointMsg`)."""

    value_class = m.JointTrajectoryPointMsg

    @classmethod
    def example(cls) -> Any:
        return m.JointTrajectoryPointMsg(positions=[0.1, 0.2], velocities=[0.0, 0.0], time_from_start=1.5)


class JointTrajectory(SupportedType):
    """A joint trajectory (:class:`~agents_core.messages.JointTrajectoryMsg`)."""

    value_class = m.JointTrajectoryMsg

    @classmethod
    def example(cls) -> Any:
        return m.JointTrajectoryMsg(joint_names=["shoulder", "elbow"],
                                    points=[JointTrajectoryPoint.example(), JointTrajectoryPoint.example()])


class JointJog(SupportedType):
    """A jog command (:class:`~agents_core.messages.JointJogMsg`)."""

    value_class = m.JointJogMsg

    @classmethod
    def example(cls) -> Any:
        return m.JointJogMsg(joint_names=["wrist"], velocities=[0.3], duration=0.5)


class OccupancyGrid(SupportedType):
    """A grid map (:class:`~agents_core.messages.OccupancyGridMsg`)."""

    value_class = m.OccupancyGridMsg

    @classmethod
    def example(cls) -> Any:
        # The origin's header is the grid's own (nav_msgs/OccupancyGrid carries one header).
        header = m.Header(stamp_ns=1_700_000_000_000_000_011, frame_id="map")
        origin = m.PoseMsg(position=[-1, -2, 0], header=m.Header(stamp_ns=header.stamp_ns, frame_id="map"))
        return m.OccupancyGridMsg(data=np.array([[0, 100], [-1, 50]], np.int8), resolution=0.1, origin=origin,
                                  header=header)


class LaserScan(SupportedType):
    """A planar scan (:class:`~agents_core.messages.LaserScanMsg`)."""

    value_class = m.LaserScanMsg

    @classmethod
    def example(cls) -> Any:
        return m.LaserScanMsg(angle_min=-1.0, angle_max=1.0, angle_increment=0.5, range_max=10.0,
                              ranges=[1, 2, 3, 4, 5], intensities=[])


class ComponentStatus(SupportedType):
    """A component's lifecycle state and health (:class:`~agents_core.messages.ComponentStatusMsg`)."""

    value_class = m.ComponentStatusMsg

    @classmethod
    def example(cls) -> Any:
        return m.ComponentStatusMsg(component="llm", lifecycle_state="active", health="HEALTHY")


# -- registry ---------------------------------------------------------------------------------

_registry: dict[str, type[SupportedType]] = {}
_registry_lock = threading.Lock()


def add_additional_datatypes(types: Iterable[type[SupportedType]]) -> None:
    """Register message types so that ``Topic(msg_type="Name")`` resolves to them.

    Re-registering the same class is a no-op; registering a *different* class under a name
    that is taken raises :class:`ConfigError` (silently shadowing a type would change the
    wiring of every recipe that names it).
    """
    with _registry_lock:
        for t in types:
            if not (isinstance(t, type) and issubclass(t, SupportedType)):
                raise ConfigError(f"{t!r} is not a SupportedType subclass")
            name = t.type_name()
            existing = _registry.get(name)
            if existing is not None and existing is not t:
                raise ConfigError(f"message type name {name!r} is already registered by {existing.__module__}")
            _registry[name] = t


def get_type(name_or_type: str | type[SupportedType]) -> type[SupportedType]:
    """Resolve a registered type by name (or check a type token); unknown names list close matches."""
    if isinstance(name_or_type, type):
        if issubclass(name_or_type, SupportedType):
            return name_or_type
        raise UnknownTypeError(f"{name_or_type.__name__} is not a SupportedType")
    if not isinstance(name_or_type, str):
        raise UnknownTypeError(f"msg_type must be a SupportedType or its name, got {type(name_or_type).__name__}")
    found = _registry.get(name_or_type)
    if found is not None:
        return found
    close = difflib.get_close_matches(name_or_type, list(_registry), n=3, cutoff=0.5)
    lowered = [n for n in _registry if n.lower() == name_or_type.lower()]
    hints = list(dict.fromkeys(lowered + close))
    hint = f"; did you mean {', '.join(repr(h) for h in hints)}?" if hints else ""
    raise UnknownTypeError(f"unknown message type {name_or_type!r}{hint} (see agents_core.registered_types())")


def registered_types() -> dict[str, type[SupportedType]]:
    """A snapshot of the registry: name -> type."""
    with _registry_lock:
        return dict(_registry)


add_additional_datatypes(
    [
        String, StreamingString, Bool, Int32, Int64, Float32, Float64, Float32MultiArray,
        Float64MultiArray, Image, CompressedImage, Audio, Video, Detections, DetectionsMultiSource,
        Trackings, TrackingsMultiSource, PointsOfInterest, Point, PointStamped, Pose, PoseStamped,
        Twist, Odometry, JointState, JointTrajectoryPoint, JointTrajectory, JointJog, OccupancyGrid,
        LaserScan, ComponentStatus,
    ]
)
