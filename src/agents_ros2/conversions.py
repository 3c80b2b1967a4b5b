"""Conversions between agents_core values and ROS 2 messages, one per registered type.

Every :class:`~agents_core.supported_types.SupportedType` in the registry has a
:class:`RosConversion`: the ROS message class it travels as, ``to_ros(value) -> message`` and
``from_ros(message) -> value``. Standard types use the standard messages (``std_msgs``,
``sensor_msgs``, ``geometry_msgs``, ``nav_msgs``, ``trajectory_msgs``); the framework's own types
use ``agents_interfaces`` (built from ``interfaces/``). A third party that registers a new
SupportedType registers its conversion here with :func:`register_conversion`.

Headers: ``Header.stamp_ns`` maps to ``stamp.sec`` / ``stamp.nanosec`` exactly, ``frame_id`` as is.
Types whose ROS message has no header (``geometry_msgs/Point``, ``Pose``, ``Twist``, the pose
inside ``nav_msgs/Odometry`` and the map origin of ``nav_msgs/OccupancyGrid``) cannot carry
one: on receipt they get the enclosing message's header, or a fresh one.

``from_ros`` raises :class:`~agents_core.errors.TypeValidationError` with the reason for a
message that has no valid value form (an image encoding other than rgb8, bgr8, rgba8, bgra8,
mono8, mono16, 16UC1; a data length that does not match the declared size; ...).
"""

from __future__ import annotations

import array
import math
import sys
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import attrs
import numpy as np
import numpy.typing as npt
from attrs import define
from builtin_interfaces.msg import Duration as RosDuration
from geometry_msgs.msg import Point as RosPoint
from geometry_msgs.msg import PointStamped as RosPointStamped
from geometry_msgs.msg import Pose as RosPose
from geometry_msgs.msg import PoseArray as RosPoseArray
from geometry_msgs.msg import PoseStamped as RosPoseStamped
from geometry_msgs.msg import Twist as RosTwist
from nav_msgs.msg import MapMetaData as RosMapMetaData
from nav_msgs.msg import OccupancyGrid as RosOccupancyGrid
from nav_msgs.msg import Odometry as RosOdometry
from nav_msgs.msg import Path as RosPath
from sensor_msgs.msg import CameraInfo as RosCameraInfo
from sensor_msgs.msg import CompressedImage as RosCompressedImage
from sensor_msgs.msg import Image as RosImage
from sensor_msgs.msg import Imu as RosImu
from sensor_msgs.msg import JointState as RosJointState
from sensor_msgs.msg import LaserScan as RosLaserScan
from sensor_msgs.msg import NavSatFix as RosNavSatFix
from sensor_msgs.msg import PointCloud2 as RosPointCloud2
from sensor_msgs.msg import PointField as RosPointField
from std_msgs.msg import Bool as RosBool
from std_msgs.msg import Float32 as RosFloat32
from std_msgs.msg import Float32MultiArray as RosFloat32MultiArray
from std_msgs.msg import Float64 as RosFloat64
from std_msgs.msg import Float64MultiArray as RosFloat64MultiArray
from std_msgs.msg import Header as RosHeader
from std_msgs.msg import Int32 as RosInt32
from std_msgs.msg import Int64 as RosInt64
from std_msgs.msg import MultiArrayDimension
from std_msgs.msg import String as RosString
from trajectory_msgs.msg import JointTrajectory as RosJointTrajectory
from trajectory_msgs.msg import JointTrajectoryPoint as RosJointTrajectoryPoint

from agents_core import messages as m
from agents_core.errors import ConfigError, TypeValidationError
from agents_core.registry import NotRegisteredError, Registry
from agents_core.status import HealthStatus
from agents_core.supported_types import SupportedType, get_type, ros_message_class, shares_value_class

with warnings.catch_warnings():
    # rclpy imports rosidl_generator_py the first time it loads a type support, which imports the
    # old lark-parser that rosidl pins, which imports the deprecated sre_parse. Importing it here,
    # once, keeps that DeprecationWarning out of user code (and out of filterwarnings=error runs).
    warnings.simplefilter("ignore", DeprecationWarning)
    import rosidl_generator_py  # noqa: F401

try:
    from agents_interfaces import msg as ai
except ImportError as exc:  # pragma: no cover - depends on the installation
    raise ImportError(
        f"the ROS 2 interface package agents_interfaces is not installed ({exc}); build it into this "
        "environment with: pip install --no-build-isolation ./interfaces (see docs/ros2.md)"
    ) from exc

__all__ = [
    "MissingConversionError",
    "RosConversion",
    "conversion_for",
    "derive_conversion",
    "from_ros",
    "register_conversion",
    "registered_conversions",
    "to_ros",
]

_NS_PER_S = 1_000_000_000
_INT32_MAX = 2**31 - 1
_NATIVE_BIG_ENDIAN = sys.byteorder == "big"
# Numpy refuses more than 64 dimensions; the Zenoh codec accepts 32, and so does this side.
_MAX_NDIM = 32


@define(frozen=True)
class RosConversion:
    """How one message type travels on ROS 2."""

    #: The ROS message class (e.g. ``sensor_msgs.msg.Image``).
    ros_type: type[Any]
    #: Value (already validated by the SupportedType) -> ROS message.
    to_ros: Callable[[Any], Any]
    #: ROS message -> value; raises TypeValidationError with the reason when it has no value form.
    from_ros: Callable[[Any], Any]


class MissingConversionError(NotRegisteredError):
    """A message type has no ROS 2 conversion (none registered, no ``_ros_type`` to derive one from)."""


_conversions: Registry[RosConversion] = Registry(
    "ROS 2 conversion", missing_error=MissingConversionError, missing_text="message type {name} has no {kind}",
    class_name=lambda cls: cls.type_name() if issubclass(cls, SupportedType) else cls.__name__,
    hint="register one with agents_ros2.conversions.register_conversion(), or give the type a _ros_type",
)


def register_conversion(
    msg_type: str | type[SupportedType],
    ros_type: type[Any],
    to_ros: Callable[[Any], Any],
    from_ros: Callable[[Any], Any],
) -> None:
    """Register how the message type ``msg_type`` (a SupportedType or its name) travels on ROS 2.

    Registering again for the same name replaces the conversion (a deliberate override).
    """
    name = get_type(msg_type).type_name()
    _conversions.register(name, RosConversion(ros_type, to_ros, from_ros), replace=True)


def registered_conversions() -> dict[str, RosConversion]:
    """A snapshot: type name -> conversion."""
    return _conversions.snapshot()


def conversion_for(msg_type: type[SupportedType]) -> RosConversion:
    """The conversion for ``msg_type``: its own, one derived from its ``_ros_type``, or its nearest base's.

    A type that declares a ``_ros_type`` of its own travels as that message: a type whose value is
    the ROS message itself (the upstream way) as is, an attrs value class field by field (see
    :func:`derive_conversion`). A subclass of a registered type with the same value class
    (``class MyImage(Image)``) uses its base's conversion: the registries' one subclass rule.
    """
    name = msg_type.type_name()
    own = _conversions.find(name)
    if own is not None:
        return own
    if "_ros_type" in vars(msg_type) and msg_type._ros_type is not None:
        return _conversions.register(name, derive_conversion(msg_type))
    found = _conversions.find_for_class(msg_type, inherits=shares_value_class)
    if found is not None:
        return found
    raise _conversions.missing(name)


def to_ros(msg_type: type[SupportedType], value: Any) -> Any:
    """Validate ``value`` as ``msg_type`` and convert it to its ROS message."""
    return conversion_for(msg_type).to_ros(msg_type.validate(value))


def from_ros(msg_type: type[SupportedType], message: Any) -> Any:
    """Convert a received ROS message to the value of ``msg_type`` (raises TypeValidationError)."""
    return conversion_for(msg_type).from_ros(message)


# -- building blocks ----------------------------------------------------------------------------


def _header_to_ros(header: m.Header, out: RosHeader) -> RosHeader:
    sec, nanosec = divmod(int(header.stamp_ns), _NS_PER_S)
    if sec > _INT32_MAX:
        raise TypeValidationError(f"header stamp {header.stamp_ns} ns does not fit ROS 2 time (int32 seconds)")
    out.stamp.sec = sec
    out.stamp.nanosec = nanosec
    out.frame_id = header.frame_id
    return out


def _header_from_ros(header: RosHeader) -> m.Header:
    if header.stamp.sec < 0:
        raise TypeValidationError(f"header stamp has negative seconds ({header.stamp.sec})")
    if header.stamp.nanosec >= _NS_PER_S:
        raise TypeValidationError(f"header stamp has {header.stamp.nanosec} nanoseconds (must be below 1e9)")
    return m.Header(stamp_ns=header.stamp.sec * _NS_PER_S + header.stamp.nanosec, frame_id=header.frame_id)


def _seq(typecode: str, values: npt.ArrayLike, dtype: type[np.generic]) -> array.array[Any]:
    """A numeric ROS sequence field: rclpy takes an ``array.array`` of the field's type without a per-item check."""
    out = array.array(typecode)
    # frombytes reads the array's buffer directly: one copy of the data (tobytes() would add one).
    out.frombytes(np.ascontiguousarray(values, dtype=dtype).data.cast("B"))
    return out


def _np(values: Any, dtype: type[np.generic]) -> npt.NDArray[Any]:
    """A received numeric sequence as numpy (zero-copy over rclpy's ``array.array`` of the same type)."""
    if isinstance(values, array.array) and np.dtype(dtype).itemsize == values.itemsize:
        return np.frombuffer(values, dtype=dtype)
    if isinstance(values, bytes):
        return np.frombuffer(values, dtype=dtype)
    return np.asarray(values, dtype=dtype)


def _f32(value: float) -> float:
    """A float32 field read back as the shortest decimal that rounds to it (0.1f -> 0.1, not 0.100000001)."""
    return float(str(np.float32(value)))


def _duration_to_ros(seconds: float) -> RosDuration:
    total = round(seconds * _NS_PER_S)
    sec, nanosec = divmod(total, _NS_PER_S)
    if not -(2**31) <= sec <= _INT32_MAX:
        raise TypeValidationError(f"duration {seconds} s does not fit ROS 2 Duration")
    return RosDuration(sec=sec, nanosec=nanosec)


def _duration_from_ros(d: RosDuration) -> float:
    return float(d.sec + d.nanosec / _NS_PER_S)


# -- scalars and text ---------------------------------------------------------------------------


def _scalar(ros_type: type[Any], read: Callable[[Any], Any]) -> RosConversion:
    return RosConversion(ros_type, lambda v: ros_type(data=v), lambda msg: read(msg.data))


def _streaming_to_ros(v: m.StreamingStringMsg) -> Any:
    out = ai.StreamingString(data=v.data, stream=v.stream, done=v.done)
    _header_to_ros(v.header, out.header)
    return out


def _streaming_from_ros(msg: Any) -> m.StreamingStringMsg:
    return m.StreamingStringMsg(data=msg.data, stream=msg.stream, done=msg.done, header=_header_from_ros(msg.header))


def _multi_array(ros_type: type[Any], typecode: str, dtype: type[np.generic]) -> RosConversion:
    def to(v: npt.NDArray[Any]) -> Any:
        out = ros_type()
        stride = int(v.size)
        for i, size in enumerate(v.shape):
            out.layout.dim.append(MultiArrayDimension(label=f"dim{i}", size=int(size), stride=stride))
            stride = stride // size if size else 0
        out.data = _seq(typecode, v.reshape(-1), dtype)
        return out

    def back(msg: Any) -> npt.NDArray[Any]:
        flat = _np(msg.data, dtype)[msg.layout.data_offset:]
        if len(msg.layout.dim) > _MAX_NDIM:
            raise TypeValidationError(f"{ros_type.__name__}: layout has {len(msg.layout.dim)} dimensions; "
                                      f"at most {_MAX_NDIM} are accepted")
        shape = tuple(int(d.size) for d in msg.layout.dim) or (flat.size,)
        # Exact Python ints: dimensions that multiply past 2**64 never wrap round to the data's size.
        if math.prod(shape) != flat.size:
            raise TypeValidationError(
                f"{ros_type.__name__}: layout {shape} needs {math.prod(shape)} values, the message has {flat.size}"
            )
        if math.prod(d for d in shape if d) * flat.itemsize >= 2**63:
            # An empty array may not claim dimensions numpy cannot even describe (0 x 2**32 x 2**32).
            raise TypeValidationError(f"{ros_type.__name__}: layout {shape} claims absurd dimensions")
        return flat.reshape(shape)

    return RosConversion(ros_type, to, back)


# -- images -------------------------------------------------------------------------------------


def _image_to_ros(v: m.ImageMsg, out: RosImage | None = None) -> RosImage:
    out = RosImage() if out is None else out
    _header_to_ros(v.header, out.header)
    data = np.ascontiguousarray(v.data)
    out.height, out.width = v.height, v.width
    out.encoding = v.encoding
    out.is_bigendian = int(_NATIVE_BIG_ENDIAN and data.dtype.itemsize > 1)
    out.step = v.width * data.shape[2] * data.dtype.itemsize
    out.data = _seq("B", data.reshape(-1).view(np.uint8), np.uint8)
    return out


def _image_from_ros(msg: RosImage) -> m.ImageMsg:
    spec = m.IMAGE_ENCODINGS.get(msg.encoding)
    if spec is None:
        raise TypeValidationError(
            f"image encoding {msg.encoding!r} is not supported (supported: {', '.join(sorted(m.IMAGE_ENCODINGS))})"
        )
    dtype, channels = spec
    itemsize = np.dtype(dtype).itemsize
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    if height > m.MAX_IMAGE_SIDE or width > m.MAX_IMAGE_SIDE:
        # Refused before anything is sized from them (an empty image may claim any width).
        raise TypeValidationError(f"image of {width}x{height} exceeds MAX_IMAGE_SIDE ({m.MAX_IMAGE_SIDE} pixels "
                                  "a side)")
    row = width * channels * itemsize
    if step < row:
        raise TypeValidationError(f"image step {step} is smaller than width {width} x {channels} channel(s) "
                                  f"x {itemsize} byte(s) = {row}")
    raw = _np(msg.data, np.uint8)
    if raw.size != step * height:
        raise TypeValidationError(f"image data has {raw.size} bytes; {msg.encoding} {width}x{height} with step "
                                  f"{step} needs {step * height}")
    rows = raw.reshape(height, step)
    if step != row:
        # Padded rows: keep only the pixels (this copies; unpadded images stay zero-copy).
        rows = np.ascontiguousarray(rows[:, :row])
    pixels = rows.view(dtype).reshape(height, width, channels)
    if itemsize > 1 and bool(msg.is_bigendian) != _NATIVE_BIG_ENDIAN:
        pixels = pixels.byteswap()
    return m.ImageMsg(data=pixels, encoding=msg.encoding, header=_header_from_ros(msg.header))


def _optional_image_to_ros(image: m.ImageMsg | None, out: RosImage) -> None:
    # ROS has no optional fields: "no image" is an Image with an empty encoding.
    if image is not None:
        _image_to_ros(image, out)


def _optional_image_from_ros(msg: RosImage) -> m.ImageMsg | None:
    return None if msg.encoding == "" else _image_from_ros(msg)


def _compressed_to_ros(v: m.CompressedImageMsg) -> RosCompressedImage:
    out = RosCompressedImage(format=v.format)
    _header_to_ros(v.header, out.header)
    out.data = _seq("B", np.frombuffer(v.data, np.uint8), np.uint8)
    return out


def _compressed_from_ros(msg: RosCompressedImage) -> m.CompressedImageMsg:
    return m.CompressedImageMsg(data=_np(msg.data, np.uint8).tobytes(), format=msg.format,
                                header=_header_from_ros(msg.header))


# -- audio and video ----------------------------------------------------------------------------

_AUDIO_FORMATS: dict[str, np.dtype[Any]] = {"S16LE": np.dtype("<i2"), "F32LE": np.dtype("<f4")}


def _audio_to_ros(v: m.AudioMsg) -> Any:
    fmt = "S16LE" if v.data.dtype == np.int16 else "F32LE"
    out = ai.Audio(sample_rate=v.sample_rate, channels=v.channels, format=fmt)
    _header_to_ros(v.header, out.header)
    out.data = _seq("B", np.ascontiguousarray(v.data, _AUDIO_FORMATS[fmt]).view(np.uint8), np.uint8)
    return out


def _audio_from_ros(msg: Any) -> m.AudioMsg:
    dtype = _AUDIO_FORMATS.get(msg.format)
    if dtype is None:
        raise TypeValidationError(f"audio format {msg.format!r} is not supported (supported: S16LE, F32LE)")
    raw = _np(msg.data, np.uint8)
    if raw.size % dtype.itemsize:
        raise TypeValidationError(f"audio data has {raw.size} bytes, not a whole number of {msg.format} samples")
    samples = raw.view(dtype).astype(dtype.newbyteorder("="), copy=False)
    return m.AudioMsg(data=samples, sample_rate=int(msg.sample_rate), channels=int(msg.channels),
                      header=_header_from_ros(msg.header))


def _video_to_ros(v: m.VideoMsg) -> Any:
    out = ai.Video()
    _header_to_ros(v.header, out.header)
    for frame in v.frames:
        if isinstance(frame, m.ImageMsg):
            out.frames.append(_image_to_ros(frame))
        else:
            out.compressed_frames.append(_compressed_to_ros(frame))
    out.frame_is_compressed = [isinstance(f, m.CompressedImageMsg) for f in v.frames]
    return out


def _video_from_ros(msg: Any) -> m.VideoMsg:
    raw = [_image_from_ros(f) for f in msg.frames]
    compressed = [_compressed_from_ros(f) for f in msg.compressed_frames]
    order = list(msg.frame_is_compressed)
    if not order:
        frames: list[m.ImageMsg | m.CompressedImageMsg] = [*raw, *compressed]
    else:
        if sum(order) != len(compressed) or len(order) - sum(order) != len(raw):
            raise TypeValidationError(f"video frame_is_compressed lists {len(order)} frames; the message has "
                                      f"{len(raw)} raw and {len(compressed)} compressed")
        raw_iter, comp_iter = iter(raw), iter(compressed)
        frames = [next(comp_iter) if is_c else next(raw_iter) for is_c in order]
    return m.VideoMsg(frames=frames, header=_header_from_ros(msg.header))


# -- perception ---------------------------------------------------------------------------------


def _boxes_to_ros(boxes: npt.NDArray[np.float32]) -> list[Any]:
    return [ai.Bbox2D(top_left_x=float(b[0]), top_left_y=float(b[1]), bottom_right_x=float(b[2]),
                      bottom_right_y=float(b[3])) for b in boxes]


def _boxes_from_ros(boxes: Sequence[Any]) -> npt.NDArray[np.float32]:
    return np.array([[b.top_left_x, b.top_left_y, b.bottom_right_x, b.bottom_right_y] for b in boxes],
                    dtype=np.float32).reshape(-1, 4)


def _points_to_ros(points: npt.NDArray[np.float32]) -> list[Any]:
    return [ai.Point2D(x=float(p[0]), y=float(p[1])) for p in points]


def _points_from_ros(points: Sequence[Any]) -> npt.NDArray[np.float32]:
    return np.array([[p.x, p.y] for p in points], dtype=np.float32).reshape(-1, 2)


def _detections_to_ros(v: m.DetectionsMsg) -> Any:
    out = ai.Detections2D(labels=list(v.labels), boxes=_boxes_to_ros(v.boxes))
    _header_to_ros(v.header, out.header)
    out.scores = _seq("f", v.scores, np.float32)
    _optional_image_to_ros(v.image, out.image)
    return out


def _detections_from_ros(msg: Any) -> m.DetectionsMsg:
    return m.DetectionsMsg(boxes=_boxes_from_ros(msg.boxes), labels=list(msg.labels),
                           scores=_np(msg.scores, np.float32), image=_optional_image_from_ros(msg.image),
                           header=_header_from_ros(msg.header))


def _trackings_to_ros(v: m.TrackingsMsg) -> Any:
    out = ai.Trackings(labels=list(v.labels), boxes=_boxes_to_ros(v.boxes), centroids=_points_to_ros(v.centroids),
                       estimated_velocities=_points_to_ros(v.estimated_velocities))
    _header_to_ros(v.header, out.header)
    out.ids = _seq("q", v.ids, np.int64)
    _optional_image_to_ros(v.image, out.image)
    return out


def _trackings_from_ros(msg: Any) -> m.TrackingsMsg:
    return m.TrackingsMsg(ids=_np(msg.ids, np.int64), labels=list(msg.labels), boxes=_boxes_from_ros(msg.boxes),
                          centroids=_points_from_ros(msg.centroids),
                          estimated_velocities=_points_from_ros(msg.estimated_velocities),
                          image=_optional_image_from_ros(msg.image), header=_header_from_ros(msg.header))


def _multi_source(ros_type: type[Any], field_name: str, item_to: Callable[[Any], Any],
                  item_from: Callable[[Any], Any]) -> RosConversion:
    def to(values: list[Any]) -> Any:
        out = ros_type(**{field_name: [item_to(v) for v in values]})
        # The list itself has no header; stamp the bundle with its first item's.
        _header_to_ros(values[0].header if values else m.Header(), out.header)
        return out

    def back(msg: Any) -> list[Any]:
        return [item_from(item) for item in getattr(msg, field_name)]

    return RosConversion(ros_type, to, back)


def _poi_to_ros(v: m.PointsOfInterestMsg) -> Any:
    out = ai.PointsOfInterest(points=_points_to_ros(v.points))
    _header_to_ros(v.header, out.header)
    _optional_image_to_ros(v.image, out.image)
    return out


def _poi_from_ros(msg: Any) -> m.PointsOfInterestMsg:
    return m.PointsOfInterestMsg(points=_points_from_ros(msg.points), image=_optional_image_from_ros(msg.image),
                                 header=_header_from_ros(msg.header))


# -- geometry and robot state -------------------------------------------------------------------


def _point_to_ros(v: m.PointMsg) -> RosPoint:
    return RosPoint(x=v.x, y=v.y, z=v.z)


# geometry_msgs Point / Pose / Twist carry no header: alone they decode with the zero header (stamp 0,
# no frame), the core's convention for "no stamp"; inside a stamped message they take its header.
def _point_from_ros(msg: RosPoint, header: m.Header | None = None) -> m.PointMsg:
    return m.PointMsg(x=msg.x, y=msg.y, z=msg.z, header=header or m.Header(stamp_ns=0))


def _point_stamped_to_ros(v: m.PointMsg) -> RosPointStamped:
    out = RosPointStamped(point=_point_to_ros(v))
    _header_to_ros(v.header, out.header)
    return out


def _point_stamped_from_ros(msg: RosPointStamped) -> m.PointMsg:
    return _point_from_ros(msg.point, _header_from_ros(msg.header))


def _pose_to_ros(v: m.PoseMsg) -> RosPose:
    out = RosPose()
    out.position.x, out.position.y, out.position.z = (float(c) for c in v.position)
    o = out.orientation
    o.x, o.y, o.z, o.w = (float(c) for c in v.orientation)
    return out


def _pose_from_ros(msg: RosPose, header: m.Header | None = None) -> m.PoseMsg:
    p, o = msg.position, msg.orientation
    return m.PoseMsg(position=[p.x, p.y, p.z], orientation=[o.x, o.y, o.z, o.w], header=header or m.Header(stamp_ns=0))


def _pose_stamped_to_ros(v: m.PoseMsg) -> RosPoseStamped:
    out = RosPoseStamped(pose=_pose_to_ros(v))
    _header_to_ros(v.header, out.header)
    return out


def _pose_stamped_from_ros(msg: RosPoseStamped) -> m.PoseMsg:
    return _pose_from_ros(msg.pose, _header_from_ros(msg.header))


def _twist_to_ros(v: m.TwistMsg) -> RosTwist:
    out = RosTwist()
    out.linear.x, out.linear.y, out.linear.z = (float(c) for c in v.linear)
    out.angular.x, out.angular.y, out.angular.z = (float(c) for c in v.angular)
    return out


def _twist_from_ros(msg: RosTwist, header: m.Header | None = None) -> m.TwistMsg:
    lin, ang = msg.linear, msg.angular
    return m.TwistMsg(linear=[lin.x, lin.y, lin.z], angular=[ang.x, ang.y, ang.z],
                      header=header or m.Header(stamp_ns=0))


def _odometry_to_ros(v: m.OdometryMsg) -> RosOdometry:
    out = RosOdometry(child_frame_id=v.child_frame_id)
    _header_to_ros(v.header, out.header)
    out.pose.pose = _pose_to_ros(v.pose)
    out.twist.twist = _twist_to_ros(v.twist)
    return out


def _odometry_from_ros(msg: RosOdometry) -> m.OdometryMsg:
    header = _header_from_ros(msg.header)
    return m.OdometryMsg(pose=_pose_from_ros(msg.pose.pose, header), twist=_twist_from_ros(msg.twist.twist, header),
                         child_frame_id=msg.child_frame_id, header=header)


def _joint_state_to_ros(v: m.JointStateMsg) -> RosJointState:
    out = RosJointState(name=list(v.name))
    _header_to_ros(v.header, out.header)
    out.position = _seq("d", v.position, np.float64)
    out.velocity = _seq("d", v.velocity, np.float64)
    out.effort = _seq("d", v.effort, np.float64)
    return out


def _joint_state_from_ros(msg: RosJointState) -> m.JointStateMsg:
    return m.JointStateMsg(name=list(msg.name), position=_np(msg.position, np.float64),
                           velocity=_np(msg.velocity, np.float64), effort=_np(msg.effort, np.float64),
                           header=_header_from_ros(msg.header))


def _trajectory_point_to_ros(v: m.JointTrajectoryPointMsg) -> RosJointTrajectoryPoint:
    out = RosJointTrajectoryPoint(time_from_start=_duration_to_ros(v.time_from_start))
    out.positions = _seq("d", v.positions, np.float64)
    out.velocities = _seq("d", v.velocities, np.float64)
    out.accelerations = _seq("d", v.accelerations, np.float64)
    out.effort = _seq("d", v.effort, np.float64)
    return out


def _trajectory_point_from_ros(msg: RosJointTrajectoryPoint) -> m.JointTrajectoryPointMsg:
    return m.JointTrajectoryPointMsg(positions=_np(msg.positions, np.float64),
                                     velocities=_np(msg.velocities, np.float64),
                                     accelerations=_np(msg.accelerations, np.float64),
                                     effort=_np(msg.effort, np.float64),
                                     time_from_start=_duration_from_ros(msg.time_from_start))


def _trajectory_to_ros(v: m.JointTrajectoryMsg) -> RosJointTrajectory:
    out = RosJointTrajectory(joint_names=list(v.joint_names), points=[_trajectory_point_to_ros(p) for p in v.points])
    _header_to_ros(v.header, out.header)
    return out


def _trajectory_from_ros(msg: RosJointTrajectory) -> m.JointTrajectoryMsg:
    return m.JointTrajectoryMsg(joint_names=list(msg.joint_names),
                                points=[_trajectory_point_from_ros(p) for p in msg.points],
                                header=_header_from_ros(msg.header))


def _jog_to_ros(v: m.JointJogMsg) -> Any:
    out = ai.JointJog(joint_names=list(v.joint_names), duration=v.duration)
    _header_to_ros(v.header, out.header)
    out.displacements = _seq("d", v.displacements, np.float64)
    out.velocities = _seq("d", v.velocities, np.float64)
    return out


def _jog_from_ros(msg: Any) -> m.JointJogMsg:
    return m.JointJogMsg(joint_names=list(msg.joint_names), displacements=_np(msg.displacements, np.float64),
                         velocities=_np(msg.velocities, np.float64), duration=msg.duration,
                         header=_header_from_ros(msg.header))


def _grid_to_ros(v: m.OccupancyGridMsg) -> RosOccupancyGrid:
    out = RosOccupancyGrid()
    _header_to_ros(v.header, out.header)
    out.info.map_load_time = out.header.stamp
    out.info.resolution = v.resolution
    out.info.height, out.info.width = (int(s) for s in v.data.shape)
    out.info.origin = _pose_to_ros(v.origin)
    out.data = _seq("b", v.data.reshape(-1), np.int8)
    return out


def _grid_from_ros(msg: RosOccupancyGrid) -> m.OccupancyGridMsg:
    cells = _np(msg.data, np.int8)
    height, width = int(msg.info.height), int(msg.info.width)
    if cells.size != height * width:
        raise TypeValidationError(f"occupancy grid data has {cells.size} cells; {width}x{height} needs "
                                  f"{height * width}")
    header = _header_from_ros(msg.header)
    return m.OccupancyGridMsg(data=cells.reshape(height, width), resolution=_f32(msg.info.resolution),
                              origin=_pose_from_ros(msg.info.origin, header), header=header)


_SCAN_SCALARS = ("angle_min", "angle_max", "angle_increment", "time_increment", "scan_time", "range_min",
                 "range_max")


def _scan_to_ros(v: m.LaserScanMsg) -> RosLaserScan:
    out = RosLaserScan(**{name: getattr(v, name) for name in _SCAN_SCALARS})
    _header_to_ros(v.header, out.header)
    out.ranges = _seq("f", v.ranges, np.float32)
    out.intensities = _seq("f", v.intensities, np.float32)
    return out


def _scan_from_ros(msg: RosLaserScan) -> m.LaserScanMsg:
    scalars = {name: _f32(getattr(msg, name)) for name in _SCAN_SCALARS}
    return m.LaserScanMsg(**scalars, ranges=_np(msg.ranges, np.float32),
                          intensities=_np(msg.intensities, np.float32), header=_header_from_ros(msg.header))


def _status_to_ros(v: m.ComponentStatusMsg) -> Any:
    try:
        health = HealthStatus[v.health]
    except KeyError:
        raise TypeValidationError(f"component status health {v.health!r} is not one of "
                                  f"{[h.name for h in HealthStatus]}") from None
    out = ai.ComponentStatus(component=v.component, lifecycle_state=v.lifecycle_state, health=int(health),
                             message=v.message)
    _header_to_ros(v.header, out.header)
    return out


def _status_from_ros(msg: Any) -> m.ComponentStatusMsg:
    try:
        health = HealthStatus(msg.health).name
    except ValueError:
        raise TypeValidationError(f"component status health code {msg.health} is unknown") from None
    return m.ComponentStatusMsg(component=msg.component, lifecycle_state=msg.lifecycle_state, health=health,
                                message=msg.message, header=_header_from_ros(msg.header))


# -- depth cameras, point clouds, inertial and satellite sensors, paths, maps ---------------------


def _rgbd_to_ros(v: m.RGBDMsg) -> Any:
    out = ai.RGBD()
    _header_to_ros(v.header, out.header)
    _image_to_ros(v.image, out.rgb)
    _image_to_ros(v.depth, out.depth)
    return out


def _rgbd_from_ros(msg: Any) -> m.RGBDMsg:
    return m.RGBDMsg(image=_image_from_ros(msg.rgb), depth=_image_from_ros(msg.depth),
                     header=_header_from_ros(msg.header))


# sensor_msgs/PointField datatypes <-> numpy dtypes (kind + size).
_POINT_FIELD_TYPES: dict[int, str] = {
    RosPointField.INT8: "i1", RosPointField.UINT8: "u1", RosPointField.INT16: "i2", RosPointField.UINT16: "u2",
    RosPointField.INT32: "i4", RosPointField.UINT32: "u4", RosPointField.FLOAT32: "f4", RosPointField.FLOAT64: "f8",
}
_POINT_FIELD_CODES = {code: datatype for datatype, code in _POINT_FIELD_TYPES.items()}


def _cloud_to_ros(v: m.PointCloud2Msg) -> RosPointCloud2:
    points = v.points
    height, width = (1, points.shape[0]) if points.ndim == 1 else points.shape
    step = points.dtype.itemsize
    out = RosPointCloud2(height=int(height), width=int(width), is_bigendian=_NATIVE_BIG_ENDIAN, point_step=step,
                         row_step=step * int(width), is_dense=v.is_dense)
    _header_to_ros(v.header, out.header)
    assert points.dtype.fields is not None  # the value class only holds structured arrays
    out.fields = [RosPointField(name=name, offset=offset, datatype=_POINT_FIELD_CODES[f"{dtype.kind}{dtype.itemsize}"],
                                count=1) for name, (dtype, offset, *_) in points.dtype.fields.items()]
    out.data = _seq("B", np.ascontiguousarray(points).reshape(-1).view(np.uint8), np.uint8)
    return out


def _cloud_from_ros(msg: RosPointCloud2) -> m.PointCloud2Msg:
    height, width, step, row_step = int(msg.height), int(msg.width), int(msg.point_step), int(msg.row_step)
    order = ">" if msg.is_bigendian else "<"
    names: list[str] = []
    formats: list[str] = []
    offsets: list[int] = []
    for f in msg.fields:
        kind = _POINT_FIELD_TYPES.get(f.datatype)
        if kind is None:
            raise TypeValidationError(f"PointCloud2 field {f.name!r}: datatype {f.datatype} is not a PointField type")
        if f.count != 1:
            raise TypeValidationError(f"PointCloud2 field {f.name!r}: count {f.count} is not supported (only 1)")
        if f.name in names:
            raise TypeValidationError(f"PointCloud2 field {f.name!r} appears twice")
        size = int(kind[1])
        if f.offset + size > step:
            raise TypeValidationError(f"PointCloud2 field {f.name!r}: offset {f.offset} + {size} bytes exceeds "
                                      f"point_step {step}")
        names.append(f.name)
        formats.append(order + kind)
        offsets.append(int(f.offset))
    if row_step < step * width:
        raise TypeValidationError(f"PointCloud2 row_step {row_step} is smaller than width {width} x point_step {step}")
    raw = _np(msg.data, np.uint8)
    if raw.size != row_step * height:
        raise TypeValidationError(f"PointCloud2 data has {raw.size} bytes; {height} rows of row_step {row_step} "
                                  f"need {row_step * height}")
    try:
        dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": step})
    except (TypeError, ValueError) as exc:
        raise TypeValidationError(f"PointCloud2 fields do not make a point layout: {exc}") from exc
    rows = raw.reshape(height, row_step)[:, :step * width] if height else raw.reshape(0, step * width)
    points = np.ascontiguousarray(rows).view(dtype).reshape(height, width)
    if msg.is_bigendian != _NATIVE_BIG_ENDIAN:
        points = points.astype(dtype.newbyteorder())
    return m.PointCloud2Msg(points=points[0] if height == 1 else points, is_dense=bool(msg.is_dense),
                            header=_header_from_ros(msg.header))


def _fixed(values: Any) -> npt.NDArray[np.float64]:
    return np.ascontiguousarray(values, dtype=np.float64)


def _imu_to_ros(v: m.ImuMsg) -> RosImu:
    out = RosImu(orientation_covariance=_fixed(v.orientation_covariance),
                 angular_velocity_covariance=_fixed(v.angular_velocity_covariance),
                 linear_acceleration_covariance=_fixed(v.linear_acceleration_covariance))
    _header_to_ros(v.header, out.header)
    o = out.orientation
    o.x, o.y, o.z, o.w = (float(c) for c in v.orientation)
    out.angular_velocity.x, out.angular_velocity.y, out.angular_velocity.z = (float(c) for c in v.angular_velocity)
    a = out.linear_acceleration
    a.x, a.y, a.z = (float(c) for c in v.linear_acceleration)
    return out


def _imu_from_ros(msg: RosImu) -> m.ImuMsg:
    o, w, a = msg.orientation, msg.angular_velocity, msg.linear_acceleration
    return m.ImuMsg(orientation=[o.x, o.y, o.z, o.w], orientation_covariance=_fixed(msg.orientation_covariance),
                    angular_velocity=[w.x, w.y, w.z],
                    angular_velocity_covariance=_fixed(msg.angular_velocity_covariance),
                    linear_acceleration=[a.x, a.y, a.z],
                    linear_acceleration_covariance=_fixed(msg.linear_acceleration_covariance),
                    header=_header_from_ros(msg.header))


def _fix_to_ros(v: m.NavSatFixMsg) -> RosNavSatFix:
    out = RosNavSatFix(latitude=float(v.latitude), longitude=float(v.longitude), altitude=float(v.altitude),
                       position_covariance=_fixed(v.position_covariance),
                       position_covariance_type=int(v.position_covariance_type))
    out.status.status, out.status.service = int(v.status), int(v.service)
    _header_to_ros(v.header, out.header)
    return out


def _fix_from_ros(msg: RosNavSatFix) -> m.NavSatFixMsg:
    return m.NavSatFixMsg(latitude=msg.latitude, longitude=msg.longitude, altitude=msg.altitude,
                          status=int(msg.status.status), service=int(msg.status.service),
                          position_covariance=_fixed(msg.position_covariance),
                          position_covariance_type=int(msg.position_covariance_type),
                          header=_header_from_ros(msg.header))


def _path_to_ros(v: m.PathMsg) -> RosPath:
    out = RosPath(poses=[_pose_stamped_to_ros(p) for p in v.poses])
    _header_to_ros(v.header, out.header)
    return out


def _path_from_ros(msg: RosPath) -> m.PathMsg:
    return m.PathMsg(poses=[_pose_stamped_from_ros(p) for p in msg.poses], header=_header_from_ros(msg.header))


def _pose_array_to_ros(v: m.PoseArrayMsg) -> RosPoseArray:
    out = RosPoseArray(poses=[_pose_to_ros(p) for p in v.poses])
    _header_to_ros(v.header, out.header)
    return out


def _pose_array_from_ros(msg: RosPoseArray) -> m.PoseArrayMsg:
    header = _header_from_ros(msg.header)
    # geometry_msgs/Pose has no header: each pose takes the array's.
    return m.PoseArrayMsg(poses=[_pose_from_ros(p, header) for p in msg.poses], header=header)


def _time_to_ros(stamp_ns: int, out: Any) -> None:
    sec, nanosec = divmod(int(stamp_ns), _NS_PER_S)
    if sec > _INT32_MAX:
        raise TypeValidationError(f"stamp {stamp_ns} ns does not fit ROS 2 time (int32 seconds)")
    out.sec, out.nanosec = sec, nanosec


def _map_info_to_ros(v: m.MapMetaDataMsg) -> RosMapMetaData:
    out = RosMapMetaData(resolution=float(v.resolution), width=int(v.width), height=int(v.height),
                         origin=_pose_to_ros(v.origin))
    _time_to_ros(v.map_load_time_ns, out.map_load_time)
    return out


def _map_info_from_ros(msg: RosMapMetaData) -> m.MapMetaDataMsg:
    t = msg.map_load_time
    if t.sec < 0 or t.nanosec >= _NS_PER_S:
        raise TypeValidationError(f"map_load_time ({t.sec} s, {t.nanosec} ns) is not a valid stamp")
    return m.MapMetaDataMsg(resolution=_f32(msg.resolution), width=int(msg.width), height=int(msg.height),
                            origin=_pose_from_ros(msg.origin), map_load_time_ns=t.sec * _NS_PER_S + t.nanosec)


def _camera_info_to_ros(v: m.CameraInfoMsg) -> RosCameraInfo:
    out = RosCameraInfo(height=int(v.height), width=int(v.width), distortion_model=v.distortion_model,
                        k=_fixed(v.k), r=_fixed(v.r), p=_fixed(v.p), binning_x=int(v.binning_x),
                        binning_y=int(v.binning_y))
    out.d = _seq("d", v.d, np.float64)
    roi = out.roi
    roi.x_offset, roi.y_offset, roi.height, roi.width = (int(c) for c in v.roi)
    roi.do_rectify = bool(v.roi_do_rectify)
    _header_to_ros(v.header, out.header)
    return out


def _camera_info_from_ros(msg: RosCameraInfo) -> m.CameraInfoMsg:
    roi = msg.roi
    return m.CameraInfoMsg(height=int(msg.height), width=int(msg.width), distortion_model=msg.distortion_model,
                           d=_np(msg.d, np.float64), k=_fixed(msg.k), r=_fixed(msg.r), p=_fixed(msg.p),
                           binning_x=int(msg.binning_x), binning_y=int(msg.binning_y),
                           roi=[roi.x_offset, roi.y_offset, roi.height, roi.width], roi_do_rectify=bool(roi.do_rectify),
                           header=_header_from_ros(msg.header))


# -- conversions derived from a type's _ros_type ----------------------------------------------

_ROS_TYPECODES: dict[str, tuple[str, type[np.generic]]] = {
    "float": ("f", np.float32), "double": ("d", np.float64), "int8": ("b", np.int8), "uint8": ("B", np.uint8),
    "int16": ("h", np.int16), "uint16": ("H", np.uint16), "int32": ("i", np.int32), "uint32": ("I", np.uint32),
    "int64": ("q", np.int64), "uint64": ("Q", np.uint64),
}


def derive_conversion(msg_type: type[SupportedType]) -> RosConversion:
    """The conversion of a type that names its ROS message in ``_ros_type``.

    A type without a value class of its own (the upstream way) uses the ROS message as its value:
    the conversion is the identity. An attrs value class is copied field by field into the
    message's fields of the same names: a :class:`~agents_core.messages.Header` into
    ``std_msgs/Header`` (stamp exact to the nanosecond), a nested value through its own type's
    conversion (an ``ImageMsg`` as ``sensor_msgs/Image``, ``None`` as an empty one), numpy arrays
    as numeric sequences, ``float`` seconds as ``builtin_interfaces/Duration``, the rest as is.
    Raises :class:`ConfigError` naming the package to install, or the field that has no counterpart.
    """
    ros_type = ros_message_class(msg_type)
    if msg_type.value_class is object:
        return RosConversion(ros_type, lambda v: v, lambda msg: msg)
    value_class = msg_type.value_class
    if not attrs.has(value_class):
        raise ConfigError(f"{msg_type.type_name()}: a _ros_type conversion needs an attrs value class or none, "
                          f"not {value_class.__name__}; register one with register_conversion()")
    ros_fields: dict[str, str] = ros_type.get_fields_and_field_types()
    copies = []
    for f in attrs.fields(value_class):
        if not f.init:
            continue
        if f.name not in ros_fields:
            raise ConfigError(f"{msg_type.type_name()}: field {f.name!r} of {value_class.__name__} has no field "
                              f"of that name in {ros_type.__module__.split('.')[0]}/{ros_type.__name__} "
                              f"(it has {sorted(ros_fields)})")
        copies.append(_field_copy(f, ros_fields[f.name]))

    def to(value: Any) -> Any:
        out = ros_type()
        for name, write, _ in copies:
            try:
                write(getattr(value, name), out, name)
            except TypeValidationError as exc:
                raise TypeValidationError(f"{msg_type.type_name()} field {name!r}: {exc}") from exc
        return out

    def back(message: Any) -> Any:
        kwargs = {}
        for name, _, read in copies:
            try:
                kwargs[name] = read(getattr(message, name))
            except TypeValidationError as exc:
                raise TypeValidationError(f"{msg_type.type_name()} field {name!r}: {exc}") from exc
        return value_class(**kwargs)

    return RosConversion(ros_type, to, back)


_Write = Callable[[Any, Any, str], None]
_Read = Callable[[Any], Any]


def _field_copy(f: attrs.Attribute[Any], ros_kind: str) -> tuple[str, _Write, _Read]:
    """How one value-class field is written into, and read from, the ROS field of the same name."""
    def assign(value: Any, out: Any, name: str) -> None:
        setattr(out, name, value)

    def header(value: Any, out: Any, name: str) -> None:
        _header_to_ros(value, getattr(out, name))

    if ros_kind == "std_msgs/Header":
        return f.name, header, _header_from_ros
    if ros_kind == "builtin_interfaces/Duration":
        return f.name, lambda v, out, name: setattr(out, name, _duration_to_ros(v)), _duration_from_ros
    if ros_kind == "sensor_msgs/Image":
        return (f.name, lambda v, out, name: _optional_image_to_ros(v, getattr(out, name)),
                _optional_image_from_ros)
    sequence = ros_kind.removeprefix("sequence<").removesuffix(">") if ros_kind.startswith("sequence<") else None
    if sequence in _ROS_TYPECODES:
        typecode, dtype = _ROS_TYPECODES[sequence]
        default: Any = f.default
        template = default.factory() if isinstance(default, attrs.Factory) else None  # type: ignore[arg-type]
        tail = tuple(template.shape[1:]) if isinstance(template, np.ndarray) else ()

        def read(values: Any) -> Any:
            flat = _np(values, dtype)
            return flat.reshape(-1, *tail) if tail else flat

        return (f.name, lambda v, out, name: setattr(out, name, _seq(typecode, np.asarray(v).reshape(-1), dtype)),
                read)
    if ros_kind == "float":
        return f.name, assign, _f32
    if ros_kind == "sequence<string>":
        return f.name, lambda v, out, name: setattr(out, name, list(v)), list
    return f.name, assign, lambda v: v


# -- the built-in table -------------------------------------------------------------------------


def _register_builtin() -> None:
    table: dict[str, RosConversion] = {
        "String": _scalar(RosString, str),
        "StreamingString": RosConversion(ai.StreamingString, _streaming_to_ros, _streaming_from_ros),
        "Bool": _scalar(RosBool, bool),
        "Int32": _scalar(RosInt32, int),
        "Int64": _scalar(RosInt64, int),
        "Float32": RosConversion(RosFloat32, lambda v: RosFloat32(data=v), lambda msg: _f32(msg.data)),
        "Float64": _scalar(RosFloat64, float),
        "Float32MultiArray": _multi_array(RosFloat32MultiArray, "f", np.float32),
        "Float64MultiArray": _multi_array(RosFloat64MultiArray, "d", np.float64),
        "Image": RosConversion(RosImage, _image_to_ros, _image_from_ros),
        "CompressedImage": RosConversion(RosCompressedImage, _compressed_to_ros, _compressed_from_ros),
        "Audio": RosConversion(ai.Audio, _audio_to_ros, _audio_from_ros),
        "Video": RosConversion(ai.Video, _video_to_ros, _video_from_ros),
        "Detections": RosConversion(ai.Detections2D, _detections_to_ros, _detections_from_ros),
        "DetectionsMultiSource": _multi_source(ai.Detections2DMultiSource, "detections", _detections_to_ros,
                                               _detections_from_ros),
        "Trackings": RosConversion(ai.Trackings, _trackings_to_ros, _trackings_from_ros),
        "TrackingsMultiSource": _multi_source(ai.TrackingsMultiSource, "trackings", _trackings_to_ros,
                                              _trackings_from_ros),
        "PointsOfInterest": RosConversion(ai.PointsOfInterest, _poi_to_ros, _poi_from_ros),
        "Point": RosConversion(RosPoint, _point_to_ros, _point_from_ros),
        "PointStamped": RosConversion(RosPointStamped, _point_stamped_to_ros, _point_stamped_from_ros),
        "Pose": RosConversion(RosPose, _pose_to_ros, _pose_from_ros),
        "PoseStamped": RosConversion(RosPoseStamped, _pose_stamped_to_ros, _pose_stamped_from_ros),
        "Twist": RosConversion(RosTwist, _twist_to_ros, _twist_from_ros),
        "Odometry": RosConversion(RosOdometry, _odometry_to_ros, _odometry_from_ros),
        "JointState": RosConversion(RosJointState, _joint_state_to_ros, _joint_state_from_ros),
        "JointTrajectoryPoint": RosConversion(RosJointTrajectoryPoint, _trajectory_point_to_ros,
                                              _trajectory_point_from_ros),
        "JointTrajectory": RosConversion(RosJointTrajectory, _trajectory_to_ros, _trajectory_from_ros),
        "JointJog": RosConversion(ai.JointJog, _jog_to_ros, _jog_from_ros),
        "OccupancyGrid": RosConversion(RosOccupancyGrid, _grid_to_ros, _grid_from_ros),
        "LaserScan": RosConversion(RosLaserScan, _scan_to_ros, _scan_from_ros),
        "ComponentStatus": RosConversion(ai.ComponentStatus, _status_to_ros, _status_from_ros),
        "RGBD": RosConversion(ai.RGBD, _rgbd_to_ros, _rgbd_from_ros),
        "PointCloud2": RosConversion(RosPointCloud2, _cloud_to_ros, _cloud_from_ros),
        "Imu": RosConversion(RosImu, _imu_to_ros, _imu_from_ros),
        "NavSatFix": RosConversion(RosNavSatFix, _fix_to_ros, _fix_from_ros),
        "Path": RosConversion(RosPath, _path_to_ros, _path_from_ros),
        "PoseArray": RosConversion(RosPoseArray, _pose_array_to_ros, _pose_array_from_ros),
        "MapMetaData": RosConversion(RosMapMetaData, _map_info_to_ros, _map_info_from_ros),
        "CameraInfo": RosConversion(RosCameraInfo, _camera_info_to_ros, _camera_info_from_ros),
    }
    for name, c in table.items():
        _conversions.register(name, attrs.evolve(c, from_ros=_overflow_to_inf(c.from_ros)))


def _overflow_to_inf(from_ros: Callable[[Any], Any]) -> Callable[[Any], Any]:
    """``from_ros`` where a float beyond float32's range becomes inf, as a C cast would, without a warning.

    rclpy accepts such a value in a float32 field of a message built in Python (its range check is
    looser than float32's), and numpy warns when casting it: that must not fail the conversion.
    """
    def convert(message: Any) -> Any:
        with np.errstate(over="ignore"):
            return from_ros(message)

    return convert


_register_builtin()
