"""The message type registry: ``SupportedType`` and the built-in types.

A :class:`SupportedType` subclass is a *type token*: it is what ``Topic(msg_type=...)`` names and
what ``allowed_inputs`` lists. It is never instantiated. It says which Python values it accepts
(:meth:`SupportedType.validate`, which also normalises convenient forms such as a bare numpy
array for an Image) and what a component's callback hands to ``_execution_step``
(:meth:`SupportedType.to_output`). Transport adapters keep their own codec per type name.

Types are looked up by name through the registry; :func:`add_additional_datatypes` registers
user-defined ones so that ``Topic(msg_type="MyType")`` resolves everywhere.

The types live in :mod:`agents_core.types`, each in its family's module beside its value class
(``Image`` in :mod:`agents_core.types.media`), the base class and the registry in
:mod:`agents_core.types.base`; this module re-exports them all (each family's at its first access).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ._lazy import lazy_facade
from .types.base import (
    SupportedType,
    _registry,  # noqa: F401 - re-exported: tests and plugins undo their registrations through it
    add_additional_datatypes,
    check_ros_message,
    get_type,
    registered_types,
    ros_message_class,
    shares_value_class,
)

if TYPE_CHECKING:
    from .types.component_status import ComponentStatus
    from .types.geometry import Odometry, Path, Point, PointStamped, Pose, PoseArray, PoseStamped, Twist
    from .types.joints import JointJog, JointState, JointTrajectory, JointTrajectoryPoint
    from .types.maps import MapMetaData, OccupancyGrid
    from .types.media import RGBD, Audio, CompressedImage, Image, Video
    from .types.perception import Detections, DetectionsMultiSource, PointsOfInterest, Trackings, TrackingsMultiSource
    from .types.scalars import Bool, Float32, Float32MultiArray, Float64, Float64MultiArray, Int32, Int64
    from .types.sensors import CameraInfo, Imu, LaserScan, NavSatFix, PointCloud2
    from .types.text import StreamingString, String
else:
    __getattr__, __dir__ = lazy_facade(__name__)

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
