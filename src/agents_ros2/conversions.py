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
import threading
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
from geometry_msgs.msg import PoseStamped as RosPoseStamped
from geometry_msgs.msg import Twist as RosTwist
from nav_msgs.msg import OccupancyGrid as RosOccupancyGrid
from nav_msgs.msg import Odometry as RosOdometry
from sensor_msgs.msg import CompressedImage as RosCompressedImage
from sensor_msgs.msg import Image as RosImage
from sensor_msgs.msg import JointState as RosJointState
from sensor_msgs.msg import LaserScan as RosLaserScan
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
from agents_core.status import HealthStatus
from agents_core.supported_types import SupportedType, get_type

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
    "RosConversion",
    "conversion_for",
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


_conversions: dict[str, RosConversion] = {}
_lock = threading.Lock()


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
    with _lock:
        _conversions[name] = RosConversion(ros_type, to_ros, from_ros)


def registered_conversions() -> dict[str, RosConversion]:
    """A snapshot: type name -> conversion."""
    with _lock:
        return dict(_conversions)


def conversion_for(msg_type: type[SupportedType]) -> RosConversion:
    """The conversion for ``msg_type``, or for the nearest registered base class of it.

    A subclass of a registered type (``class MyImage(Image)``) uses its base's conversion.
    """
    with _lock:
        for cls in msg_type.__mro__:
            if isinstance(cls, type) and issubclass(cls, SupportedType) and cls is not SupportedType:
                found = _conversions.get(cls.type_name())
                if found is not None:
                    return found
    raise ConfigError(
        f"message type {msg_type.type_name()!r} has no ROS 2 conversion; register one with "
        "agents_ros2.conversions.register_conversion()"
    )


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
    }
    with _lock:
        _conversions.update({name: attrs.evolve(c, from_ros=_overflow_to_inf(c.from_ros)) for name, c in table.items()})


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
