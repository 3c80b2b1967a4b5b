"""The message types, by family: each value class beside the :class:`~.base.SupportedType` that names it.

- :mod:`.base`: :class:`~.base.SupportedType`, the registry (:func:`~.base.add_additional_datatypes`,
  :func:`~.base.get_type`) and the checks of ROS-message values;
- :mod:`.fields`: :class:`~.fields.Header` and the validators and converters the value classes share;
- the families: :mod:`.text`, :mod:`.scalars`, :mod:`.media`, :mod:`.perception`, :mod:`.geometry`,
  :mod:`.joints`, :mod:`.maps`, :mod:`.sensors`, :mod:`.component_status`.

Users import these names from :mod:`agents_core.messages` (the value classes) and
:mod:`agents_core.supported_types` (the types and the registry), which re-export them.

Importing any module of this package registers every built-in type (this ``__init__`` runs first),
in :data:`BUILTIN_TYPES` order: codecs, the schema document and the conformance suite list the
types in that order. To add a built-in type: put its value class and type in their family's
module, then append the type to :data:`BUILTIN_TYPES`.
"""

from __future__ import annotations

from .base import SupportedType, add_additional_datatypes
from .component_status import ComponentStatus
from .geometry import Odometry, Path, Point, PointStamped, Pose, PoseArray, PoseStamped, Twist
from .joints import JointJog, JointState, JointTrajectory, JointTrajectoryPoint
from .maps import MapMetaData, OccupancyGrid
from .media import RGBD, Audio, CompressedImage, Image, Video
from .perception import Detections, DetectionsMultiSource, PointsOfInterest, Trackings, TrackingsMultiSource
from .scalars import Bool, Float32, Float32MultiArray, Float64, Float64MultiArray, Int32, Int64
from .sensors import CameraInfo, Imu, LaserScan, NavSatFix, PointCloud2
from .text import StreamingString, String

__all__ = ["BUILTIN_TYPES", "is_builtin_type"]

#: The framework's own message types, in registration order (the order predates the families:
#: types added later come last, whatever their family).
BUILTIN_TYPES: tuple[type[SupportedType], ...] = (
    String, StreamingString, Bool, Int32, Int64, Float32, Float64, Float32MultiArray,
    Float64MultiArray, Image, CompressedImage, Audio, Video, Detections, DetectionsMultiSource,
    Trackings, TrackingsMultiSource, PointsOfInterest, Point, PointStamped, Pose, PoseStamped,
    Twist, Odometry, JointState, JointTrajectoryPoint, JointTrajectory, JointJog, OccupancyGrid,
    LaserScan, ComponentStatus, RGBD, PointCloud2, Imu, NavSatFix, Path, PoseArray, MapMetaData,
    CameraInfo,
)


def is_builtin_type(msg_type: type) -> bool:
    """True for the framework's own message types (:data:`BUILTIN_TYPES`), False for user-registered ones."""
    return msg_type in BUILTIN_TYPES


add_additional_datatypes(BUILTIN_TYPES)
