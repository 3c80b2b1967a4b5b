"""The upstream ``agents.ros`` names, for recipes migrating from EmbodiedAgents.

``from agents_core.ros import Topic, Launcher, Image`` works as ``from agents.ros import ...``
did upstream. Nothing here depends on ROS: each name lives in a descriptive module of its own
and works on every transport.

Upstream names with no counterpart here: ``BaseComponent`` (write ``Component``, from
:mod:`agents_core.components`), ``Monitor`` (the launcher supervises), ``VisionLanguageAction``
(the VLA component is ``agents_core.components.VLA``), and the rclpy helpers
``MutuallyExclusiveCallbackGroup``, ``ServiceClientHandler``, ``ActionClientHandler``,
``run_external_processor``, ``get_ros_msg_fields_dict``, ``ros_msg_to_str``,
``get_methods_with_decorator`` and ``ActionPhase``. ``MemLayer`` and ``Memory`` are here (the
Memory component, :mod:`agents_core.components.memory`). Upstream's ``actions``
module is :mod:`agents_core.actions` (its names, ``Action`` and the decorators, are here).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ._lazy import lazy_facade

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
    __getattr__, __dir__ = lazy_facade(__name__)

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
