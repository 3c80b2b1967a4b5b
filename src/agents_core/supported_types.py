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

import array
import importlib
import math
from collections.abc import Iterable, Sequence
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from . import messages as m
from .errors import ConfigError, TypeValidationError, UnknownTypeError
from .registry import DuplicateNameError, Registry

__all__ = [
    "RGBD",
    "Audio",
    "Bool",
    "CameraInfo",
    "ComponentStatus",
    "CompressedImage",
    "Detections",
    "DetectionsMultiSource",
    "Float32",
    "Float32MultiArray",
    "Float64",
    "Float64MultiArray",
    "Image",
    "Imu",
    "Int32",
    "Int64",
    "JointJog",
    "JointState",
    "JointTrajectory",
    "JointTrajectoryPoint",
    "LaserScan",
    "MapMetaData",
    "NavSatFix",
    "OccupancyGrid",
    "Odometry",
    "Path",
    "Point",
    "PointCloud2",
    "PointStamped",
    "PointsOfInterest",
    "Pose",
    "PoseArray",
    "PoseStamped",
    "StreamingString",
    "String",
    "SupportedType",
    "Trackings",
    "TrackingsMultiSource",
    "Twist",
    "Video",
    "add_additional_datatypes",
    "check_ros_message",
    "get_type",
    "registered_types",
    "ros_message_class",
    "shares_value_class",
]


class SupportedType:
    """Base of every message type token.

    Subclasses set :attr:`value_class` (the Python class of a validated value) and override
    :meth:`validate` when they accept more than instances of it. Subclassing an existing type
    makes the new one acceptable wherever the parent is allowed (``StreamingString`` passes where
    ``String`` is required).

    The upstream extension hooks (messages.md, custom_component.md) work as written there:

    - ``_ros_type``: the ROS message class (or its name, ``"pkg/msg/Name"``) the type travels as
      on ROS 2. A type with a ``_ros_type`` and no :attr:`value_class` of its own uses the ROS
      message itself as its value, on every transport (Zenoh sends its fields as a msgpack map).
    - ``convert(output, **kwargs)``: turns what a component publishes (a dict, an array, ...)
      into the type's value; :meth:`validate` calls it for anything that is not a value already.
    - ``callback``: the :class:`~agents_core.callbacks.GenericCallback` subclass that components
      create for inputs of this type; its ``_msg_to_output`` / ``_get_output`` give ``get_output()``.
    """

    value_class: ClassVar[type[Any]] = object
    #: The ROS message class (or ``"pkg/msg/Name"``) this type travels as on ROS 2 (None: the adapter's table).
    _ros_type: ClassVar[Any] = None
    #: The callback class components create for inputs of this type (None: GenericCallback).
    callback: ClassVar[type[Any] | None] = None

    @classmethod
    def type_name(cls) -> str:
        """The registry name (the class name)."""
        return cls.__name__

    @classmethod
    def message_class(cls) -> type[Any]:
        """The class of this type's values: :attr:`value_class`, else the ROS message of ``_ros_type``."""
        if cls.value_class is object and cls._ros_type is not None:
            return ros_message_class(cls)
        return cls.value_class

    @classmethod
    def validate(cls, value: Any) -> Any:
        """Return ``value`` in this type's canonical form, or raise :class:`TypeValidationError`."""
        message_class = cls.message_class()
        if not isinstance(value, message_class) and _overrides_convert(cls):
            value = _converted(cls, value, message_class)
        if isinstance(value, message_class):
            if message_class is not cls.value_class:
                # A ROS message (rosidl checks field types only with ROS_PYTHON_CHECK_FIELDS=1): check it here,
                # so that a bad field fails on publish, naming it, on every transport.
                check_ros_message(value, cls.type_name())
            return value
        raise TypeValidationError(
            f"{cls.type_name()} expects {message_class.__name__}, got {type(value).__name__}"
        )

    @classmethod
    def convert(cls, output: Any, **kwargs: Any) -> Any:
        """What a component's ``output`` is published as (the upstream hook; default :meth:`validate`)."""
        return cls.validate(output)

    @classmethod
    def to_output(cls, value: Any) -> Any:
        """What a callback's ``get_output()`` returns for a received value (default: the value)."""
        return value

    @classmethod
    def example(cls) -> Any:
        """A small valid value, used for warm-ups and by the transport conformance tests."""
        raise NotImplementedError(f"{cls.type_name()} has no example value")


def _overrides_convert(cls: type[SupportedType]) -> bool:
    return cls.convert.__func__ is not SupportedType.convert.__func__  # type: ignore[attr-defined]


def _converted(cls: type[SupportedType], value: Any, message_class: type[Any]) -> Any:
    """``cls.convert(value)``, its failures as a TypeValidationError naming the type and, where known, the field."""
    name = cls.type_name()
    try:
        out = cls.convert(value)
    except TypeValidationError as exc:
        raise TypeValidationError(f"{name}: {exc}") from exc
    except KeyError as exc:
        raise TypeValidationError(f"{name}: field {exc.args[0]!r} is missing from the {type(value).__name__} "
                                  "to convert") from exc
    except Exception as exc:
        # rosidl's setters name the field ("The 'confidence' field must be of type 'float'").
        raise TypeValidationError(f"{name}: cannot convert {type(value).__name__} {_short(value)}: "
                                  f"{type(exc).__name__}: {exc}") from exc
    if not isinstance(out, message_class):
        raise TypeValidationError(f"{name}.convert returned {type(out).__name__}, not {message_class.__name__}")
    return out


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


_ROS_INT_BITS = {"int8": 8, "int16": 16, "int32": 32, "int64": 64, "char": 8}
_ROS_UINT_BITS = {"uint8": 8, "uint16": 16, "uint32": 32, "uint64": 64, "octet": 8, "byte": 8}
_F32_MAX = float(np.finfo(np.float32).max)


def check_ros_message(message: Any, where: str) -> None:
    """Raise :class:`TypeValidationError` naming the first field of a ROS message whose value does not fit its type."""
    fields: dict[str, str] = type(message).get_fields_and_field_types()
    for name, kind in fields.items():
        _check_ros_field(getattr(message, name), kind, f"{where} field {name!r}")


def _check_ros_field(value: Any, kind: str, where: str) -> None:
    base, _, bound = kind.partition("[")
    if kind.startswith("sequence<"):
        base, bound = kind[len("sequence<"):].partition(">")[0].partition(",")[0], ""
    elif not bound:
        _check_ros_scalar(value, kind, where)
        return
    if isinstance(value, array.array | np.ndarray | bytes):
        return  # typed storage: rosidl built it for the field's type
    if not isinstance(value, list | tuple):
        raise TypeValidationError(f"{where}: expected a sequence of {base}, got {type(value).__name__}")
    fixed = bound.rstrip("]")
    if fixed.isdigit() and len(value) != int(fixed):
        raise TypeValidationError(f"{where}: expected {fixed} values, got {len(value)}")
    for i, item in enumerate(value):
        _check_ros_scalar(item, base, f"{where}[{i}]")


def _check_ros_scalar(value: Any, kind: str, where: str) -> None:
    problem = ""
    if kind.startswith(("string", "wstring")):
        problem = "" if isinstance(value, str) else "str"
    elif kind == "boolean":
        problem = "" if isinstance(value, bool | np.bool_) else "bool"
    elif kind in ("float", "double"):
        if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
            problem = "a number"
        elif kind == "float" and math.isfinite(float(value)) and abs(float(value)) > _F32_MAX:
            problem = "a number within float32's range"
    elif kind in _ROS_INT_BITS or kind in _ROS_UINT_BITS:
        signed = kind in _ROS_INT_BITS
        bits = _ROS_INT_BITS[kind] if signed else _ROS_UINT_BITS[kind]
        low, high = (-(2 ** (bits - 1)), 2 ** (bits - 1)) if signed else (0, 2**bits)
        if isinstance(value, bytes) and len(value) == 1:
            return
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or not low <= int(value) < high:
            problem = f"an int in [{low}, {high - 1}]"
    elif hasattr(value, "get_fields_and_field_types"):
        check_ros_message(value, where)
    if problem:
        raise TypeValidationError(f"{where}: expected {problem} ({kind}), got {type(value).__name__} {value!r:.40}")


def ros_message_class(msg_type: type[SupportedType]) -> type[Any]:
    """The ROS message class named by ``msg_type._ros_type`` (a class, ``"pkg/msg/Name"`` or ``"pkg.msg.Name"``).

    Raises :class:`ConfigError` saying which package to install when it cannot be imported.
    """
    ros_type = msg_type._ros_type
    if isinstance(ros_type, type):
        return ros_type
    if not isinstance(ros_type, str):
        raise ConfigError(f"{msg_type.type_name()}._ros_type must be a ROS message class or 'pkg/msg/Name', "
                          f"got {ros_type!r}")
    parts = ros_type.replace(".", "/").split("/")
    if len(parts) == 2:
        parts.insert(1, "msg")
    if len(parts) != 3 or not all(parts):
        raise ConfigError(f"{msg_type.type_name()}._ros_type {ros_type!r} is not of the form 'pkg/msg/Name'")
    package, kind, name = parts
    try:
        module = importlib.import_module(f"{package}.{kind}")
    except ImportError as exc:
        raise ConfigError(
            f"message type {msg_type.type_name()!r} travels as {package}/{kind}/{name}, but the ROS package "
            f"{package!r} is not installed in this environment ({exc}); build and install it (for a package of "
            "your own: pip install --no-build-isolation ./your_interfaces, see docs/ros2.md)"
        ) from exc
    found = getattr(module, name, None)
    if not isinstance(found, type):
        raise ConfigError(f"message type {msg_type.type_name()!r}: package {package!r} has no message {name!r}")
    return found


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
    """An n-dimensional float32 numpy array; array-likes (nested lists) are converted."""

    value_class = np.ndarray
    dtype: ClassVar[type[np.generic]] = np.float32

    @classmethod
    def validate(cls, value: Any) -> Any:
        if isinstance(value, np.ndarray) and value.dtype == cls.dtype:
            return value
        if isinstance(value, np.ndarray | Sequence) and not isinstance(value, str | bytes):
            try:
                arr: npt.NDArray[Any] = m.as_numeric_array(value, None, "data")
                if arr.dtype.kind != "b":  # booleans are not numbers here, as before
                    return m.as_numeric_array(arr, cls.dtype, "data")
            except TypeValidationError as exc:
                raise TypeValidationError(f"{cls.type_name()} {exc}") from exc
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

    ``get_output()`` gives the pixels as a numpy array, RGB for colour encodings. Nested lists
    (a model server's JSON reply) are converted: integers from 0 to 255 as uint8.
    """

    value_class: ClassVar[type[Any]] = m.ImageMsg

    @classmethod
    def validate(cls, value: Any) -> Any:
        if isinstance(value, np.ndarray | list):
            try:
                return m.ImageMsg.from_array(value)
            except TypeValidationError as exc:
                raise TypeValidationError(f"Image {exc}") from exc
        return super().validate(value)

    @classmethod
    def to_output(cls, value: Any) -> Any:
        return value.to_rgb()

    @classmethod
    def example(cls) -> Any:
        pixels = np.arange(4 * 5 * 3, dtype=np.uint8).reshape(4, 5, 3)
        return m.ImageMsg(data=pixels, encoding="rgb8", header=m.Header(stamp_ns=1_700_000_000_123_456_789,
                                                                        frame_id="camera"))


class RGBD(Image):
    """An aligned colour + depth frame (:class:`~agents_core.messages.RGBDMsg`).

    A subtype of Image, so it is accepted wherever Image is (a VLM, Vision or VLA input): there
    ``get_output()`` gives the colour pixels, as for an Image; ``callback.msg`` keeps the depth.
    A pair ``(image, depth)`` of arrays or ImageMsgs is wrapped.
    """

    value_class = m.RGBDMsg

    @classmethod
    def validate(cls, value: Any) -> Any:
        if isinstance(value, m.RGBDMsg):
            return value
        if isinstance(value, tuple) and len(value) == 2:
            image, depth = (v if isinstance(v, m.ImageMsg) else m.ImageMsg.from_array(v) for v in value)
            return m.RGBDMsg(image=image, depth=depth, header=image.header)
        raise TypeValidationError(f"RGBD expects RGBDMsg or an (image, depth) pair, got {type(value).__name__}")

    @classmethod
    def example(cls) -> Any:
        header = m.Header(stamp_ns=1_700_000_000_000_000_021, frame_id="camera_color_optical_frame")
        depth = m.ImageMsg(data=np.arange(20, dtype=np.uint16).reshape(4, 5) * 100, encoding="16UC1",
                           header=header)
        image = Image.example()
        return m.RGBDMsg(image=m.ImageMsg(data=image.data, encoding="rgb8", header=header), depth=depth,
                         header=header)


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


class PointCloud2(SupportedType):
    """A point cloud (:class:`~agents_core.messages.PointCloud2Msg`); a structured array is wrapped."""

    value_class = m.PointCloud2Msg

    @classmethod
    def validate(cls, value: Any) -> Any:
        if isinstance(value, np.ndarray):
            return m.PointCloud2Msg(points=value)
        return super().validate(value)

    @classmethod
    def example(cls) -> Any:
        # PCL's XYZRGB layout: x, y, z, 4 bytes of padding, rgb packed in a float32; 32 bytes a point.
        dtype = np.dtype({"names": ["x", "y", "z", "rgb"], "formats": ["<f4", "<f4", "<f4", "<u4"],
                          "offsets": [0, 4, 8, 16], "itemsize": 32})
        points = np.zeros(3, dtype)
        points["x"], points["y"], points["z"] = [1.0, 2.0, 3.0], [0.5, -0.5, 0.0], [0.1, 0.2, 0.3]
        points["rgb"] = [0xFF0000, 0x00FF00, 0x0000FF]
        return m.PointCloud2Msg(points=points, header=m.Header(stamp_ns=1_700_000_000_000_000_023,
                                                               frame_id="lidar"))


class Imu(SupportedType):
    """An inertial measurement (:class:`~agents_core.messages.ImuMsg`)."""

    value_class = m.ImuMsg

    @classmethod
    def example(cls) -> Any:
        return m.ImuMsg(orientation=[0, 0, 0.38268343, 0.92387953], orientation_covariance=[-1] + [0] * 8,
                        angular_velocity=[0.01, -0.02, 0.3], angular_velocity_covariance=np.eye(3).reshape(-1) * 1e-4,
                        linear_acceleration=[0.1, 0.0, 9.81], linear_acceleration_covariance=[np.nan] * 9,
                        header=m.Header(stamp_ns=1_700_000_000_000_000_025, frame_id="imu_link"))


class NavSatFix(SupportedType):
    """A satellite fix (:class:`~agents_core.messages.NavSatFixMsg`)."""

    value_class = m.NavSatFixMsg

    @classmethod
    def example(cls) -> Any:
        return m.NavSatFixMsg(latitude=48.858370, longitude=2.294481, altitude=35.5, status=0, service=1,
                              position_covariance=[4.0, 0, 0, 0, 4.0, 0, 0, 0, 9.0], position_covariance_type=2,
                              header=m.Header(stamp_ns=1_700_000_000_000_000_027, frame_id="gps"))


class Path(SupportedType):
    """A path of stamped poses (:class:`~agents_core.messages.PathMsg`)."""

    value_class = m.PathMsg

    @classmethod
    def example(cls) -> Any:
        header = m.Header(stamp_ns=1_700_000_000_000_000_029, frame_id="map")
        poses = [m.PoseMsg(position=[i, 0.5 * i, 0], header=m.Header(stamp_ns=header.stamp_ns + i, frame_id="map"))
                 for i in range(3)]
        return m.PathMsg(poses=poses, header=header)


class PoseArray(SupportedType):
    """Poses in one frame (:class:`~agents_core.messages.PoseArrayMsg`)."""

    value_class = m.PoseArrayMsg

    @classmethod
    def example(cls) -> Any:
        # geometry_msgs/PoseArray carries one header: the poses share it.
        header = m.Header(stamp_ns=1_700_000_000_000_000_031, frame_id="base_link")
        poses = [m.PoseMsg(position=[1, 2, 3], orientation=[0, 0, 0, 1], header=header),
                 m.PoseMsg(position=[-1, 0, 0.5], orientation=[0, 0, 1, 0], header=header)]
        return m.PoseArrayMsg(poses=poses, header=header)


class MapMetaData(SupportedType):
    """A grid map's geometry (:class:`~agents_core.messages.MapMetaDataMsg`)."""

    value_class = m.MapMetaDataMsg

    @classmethod
    def example(cls) -> Any:
        # nav_msgs/MapMetaData has no header: the origin pose has none (stamp 0) either.
        return m.MapMetaDataMsg(resolution=0.05, width=200, height=100, origin=m.PoseMsg(position=[-5, -2.5, 0],
                                header=_unstamped()), map_load_time_ns=1_700_000_000_000_000_033)


class CameraInfo(SupportedType):
    """A camera calibration (:class:`~agents_core.messages.CameraInfoMsg`)."""

    value_class = m.CameraInfoMsg

    @classmethod
    def example(cls) -> Any:
        k = [525.0, 0, 319.5, 0, 525.0, 239.5, 0, 0, 1]
        return m.CameraInfoMsg(height=480, width=640, distortion_model="plumb_bob", d=[0.1, -0.2, 0, 0, 0.05],
                               k=k, r=np.eye(3).reshape(-1), p=[525.0, 0, 319.5, 0, 0, 525.0, 239.5, 0, 0, 0, 1, 0],
                               binning_x=1, binning_y=1, roi=[0, 0, 480, 640], roi_do_rectify=False,
                               header=m.Header(stamp_ns=1_700_000_000_000_000_035, frame_id="camera"))


class ComponentStatus(SupportedType):
    """A component's lifecycle state and health (:class:`~agents_core.messages.ComponentStatusMsg`)."""

    value_class = m.ComponentStatusMsg

    @classmethod
    def example(cls) -> Any:
        return m.ComponentStatusMsg(component="llm", lifecycle_state="active", health="HEALTHY")


# -- registry ---------------------------------------------------------------------------------


def shares_value_class(cls: type, base: type) -> bool:
    """The registries' subclass rule: ``cls`` may use ``base``'s entry (codec, conversion) when both are
    message types with the same value class, so that the entry's wire form fits ``cls``'s values."""
    return (isinstance(base, type) and issubclass(base, SupportedType) and base is not SupportedType
            and issubclass(cls, SupportedType) and base.value_class is cls.value_class)


_registry: Registry[type[SupportedType]] = Registry(
    "message type", hint="see agents_core.registered_types()", class_name=lambda cls: cls.__name__,
)


def add_additional_datatypes(types: Iterable[type[SupportedType]]) -> None:
    """Register message types so that ``Topic(msg_type="Name")`` resolves to them.

    Re-registering the same class is a no-op; registering a *different* class under a name
    that is taken raises :class:`ConfigError` (silently shadowing a type would change the
    wiring of every recipe that names it).
    """
    for t in types:
        if not (isinstance(t, type) and issubclass(t, SupportedType)):
            raise ConfigError(f"{t!r} is not a SupportedType subclass")
        name = t.type_name()
        existing = _registry.find(name)
        if existing is not None and existing is not t:
            raise DuplicateNameError(f"message type name {name!r} is already registered by {existing.__module__}")
        _registry.register(name, t)


def get_type(name_or_type: str | type[SupportedType]) -> type[SupportedType]:
    """Resolve a registered type by name (or check a type token); unknown names list close matches."""
    if isinstance(name_or_type, type):
        if issubclass(name_or_type, SupportedType):
            name_or_type.message_class()
            return name_or_type
        raise UnknownTypeError(f"{name_or_type.__name__} is not a SupportedType")
    if not isinstance(name_or_type, str):
        raise UnknownTypeError(f"msg_type must be a SupportedType or its name, got {type(name_or_type).__name__}")
    found = _registry.get(name_or_type)
    found.message_class()  # a _ros_type from a package that is not installed fails here, at topic creation
    return found


def registered_types() -> dict[str, type[SupportedType]]:
    """A snapshot of the registry: name -> type."""
    return _registry.snapshot()


add_additional_datatypes(
    [
        String, StreamingString, Bool, Int32, Int64, Float32, Float64, Float32MultiArray,
        Float64MultiArray, Image, CompressedImage, Audio, Video, Detections, DetectionsMultiSource,
        Trackings, TrackingsMultiSource, PointsOfInterest, Point, PointStamped, Pose, PoseStamped,
        Twist, Odometry, JointState, JointTrajectoryPoint, JointTrajectory, JointJog, OccupancyGrid,
        LaserScan, ComponentStatus, RGBD, PointCloud2, Imu, NavSatFix, Path, PoseArray, MapMetaData,
        CameraInfo,
    ]
)
