"""The upstream ``agents.ros`` names, for recipes migrating from EmbodiedAgents.

``from agents_core.ros import Topic, Launcher, Image`` works as ``from agents.ros import ...``
did upstream. Nothing here depends on ROS: each name lives in a descriptive module of its own
and works on every transport.

Upstream names with no counterpart here: ``BaseComponent`` (write ``Component``, from
:mod:`agents_core.components`), ``Monitor`` (the launcher supervises), ``MemLayer`` (no Memory
component yet), ``VisionLanguageAction`` (the VLA component is ``agents_core.components.VLA``), and
the rclpy helpers ``MutuallyExclusiveCallbackGroup``, ``ServiceClientHandler``,
``ActionClientHandler``, ``run_external_processor``, ``get_ros_msg_fields_dict``,
``ros_msg_to_str``, ``get_methods_with_decorator`` and ``ActionPhase``. Upstream's ``actions``
module is :mod:`agents_core.actions` (its names, ``Action`` and the decorators, are here).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ._lazy import lazy_exports

#: module -> the names re-exported from it, imported on first access: ``from agents_core.ros import
#: Topic, Launcher, String`` loads the launcher and the type table, never the model components or clients.
_EXPORTS: dict[str, tuple[str, ...]] = {
    ".actions": ("Action", "Fallback", "component_action", "component_fallback"),
    ".components.map_encoding": ("MapLayer",),
    ".components.memory": ("MemLayer", "Memory", "MemoryConfig"),
    ".components.semantic_router": ("Route",),
    ".config": ("BaseAttrs", "BaseComponentConfig"),
    ".events": ("Event",),
    ".launch.launcher": ("Launcher",),
    ".runtime.run_type": ("ComponentRunType",),
    ".status": ("HealthStatus", "LifecycleState"),
    ".supported_types": (
        "Audio", "Bool", "CameraInfo", "ComponentStatus", "CompressedImage", "Detections", "DetectionsMultiSource",
        "Float32", "Float32MultiArray", "Float64", "Float64MultiArray", "Image", "Imu", "Int32", "Int64", "JointJog",
        "JointState", "JointTrajectory", "JointTrajectoryPoint", "LaserScan", "MapMetaData", "NavSatFix",
        "OccupancyGrid", "Odometry", "Path", "Point", "PointCloud2", "PointsOfInterest", "PointStamped", "Pose",
        "PoseArray", "PoseStamped", "RGBD", "StreamingString", "String", "SupportedType", "Trackings",
        "TrackingsMultiSource", "Twist", "Video", "add_additional_datatypes",
    ),
    ".callbacks": ("GenericCallback",),
    ".topics": ("FixedInput", "QoSConfig", "Topic"),
}
#: re-exported names that are modules themselves: name -> module.
_MODULE_EXPORTS = {"base_validators": ".base_validators"}

if TYPE_CHECKING:
    from . import base_validators
    from .actions import Action, Fallback, component_action, component_fallback
    from .callbacks import GenericCallback
    from .components.map_encoding import MapLayer
    from .components.memory import MemLayer, Memory, MemoryConfig
    from .components.semantic_router import Route
    from .config import BaseAttrs, BaseComponentConfig
    from .events import Event
    from .launch.launcher import Launcher
    from .runtime.run_type import ComponentRunType
    from .status import HealthStatus, LifecycleState
    from .supported_types import (
        RGBD,
        Audio,
        Bool,
        CameraInfo,
        ComponentStatus,
        CompressedImage,
        Detections,
        DetectionsMultiSource,
        Float32,
        Float32MultiArray,
        Float64,
        Float64MultiArray,
        Image,
        Imu,
        Int32,
        Int64,
        JointJog,
        JointState,
        JointTrajectory,
        JointTrajectoryPoint,
        LaserScan,
        MapMetaData,
        NavSatFix,
        OccupancyGrid,
        Odometry,
        Path,
        Point,
        PointCloud2,
        PointsOfInterest,
        PointStamped,
        Pose,
        PoseArray,
        PoseStamped,
        StreamingString,
        String,
        SupportedType,
        Trackings,
        TrackingsMultiSource,
        Twist,
        Video,
        add_additional_datatypes,
    )
    from .topics import FixedInput, QoSConfig, Topic
else:
    __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, modules=_MODULE_EXPORTS)

__all__ = [
    "RGBD",
    "Action",
    "Audio",
    "BaseAttrs",
    "BaseComponentConfig",
    "Bool",
    "CameraInfo",
    "ComponentRunType",
    "ComponentStatus",
    "CompressedImage",
    "Detections",
    "DetectionsMultiSource",
    "Event",
    "Fallback",
    "FixedInput",
    "Float32",
    "Float32MultiArray",
    "Float64",
    "Float64MultiArray",
    "GenericCallback",
    "HealthStatus",
    "Image",
    "Imu",
    "Int32",
    "Int64",
    "JointJog",
    "JointState",
    "JointTrajectory",
    "JointTrajectoryPoint",
    "LaserScan",
    "Launcher",
    "LifecycleState",
    "MapLayer",
    "MapMetaData",
    "MemLayer",
    "Memory",
    "MemoryConfig",
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
    "QoSConfig",
    "Route",
    "StreamingString",
    "String",
    "SupportedType",
    "Topic",
    "Trackings",
    "TrackingsMultiSource",
    "Twist",
    "Video",
    "add_additional_datatypes",
    "base_validators",
    "component_action",
    "component_fallback",
]
