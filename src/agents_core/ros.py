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

from .support.lazy import lazy_facade

if TYPE_CHECKING:
    from . import base_validators as base_validators
    from .actions import Action as Action
    from .actions import Fallback as Fallback
    from .actions import component_action as component_action
    from .actions import component_fallback as component_fallback
    from .callbacks import GenericCallback as GenericCallback
    from .components.map_encoding import MapLayer as MapLayer
    from .components.memory import MemLayer as MemLayer
    from .components.memory import Memory as Memory
    from .components.memory import MemoryConfig as MemoryConfig
    from .components.semantic_router import Route as Route
    from .config import BaseAttrs as BaseAttrs
    from .config import BaseComponentConfig as BaseComponentConfig
    from .events import Event as Event
    from .launch.launcher import Launcher as Launcher
    from .runtime.run_type import ComponentRunType as ComponentRunType
    from .status import HealthStatus as HealthStatus
    from .status import LifecycleState as LifecycleState
    from .supported_types import RGBD as RGBD
    from .supported_types import Audio as Audio
    from .supported_types import Bool as Bool
    from .supported_types import CameraInfo as CameraInfo
    from .supported_types import ComponentStatus as ComponentStatus
    from .supported_types import CompressedImage as CompressedImage
    from .supported_types import Detections as Detections
    from .supported_types import DetectionsMultiSource as DetectionsMultiSource
    from .supported_types import Float32 as Float32
    from .supported_types import Float32MultiArray as Float32MultiArray
    from .supported_types import Float64 as Float64
    from .supported_types import Float64MultiArray as Float64MultiArray
    from .supported_types import Image as Image
    from .supported_types import Imu as Imu
    from .supported_types import Int32 as Int32
    from .supported_types import Int64 as Int64
    from .supported_types import JointJog as JointJog
    from .supported_types import JointState as JointState
    from .supported_types import JointTrajectory as JointTrajectory
    from .supported_types import JointTrajectoryPoint as JointTrajectoryPoint
    from .supported_types import LaserScan as LaserScan
    from .supported_types import MapMetaData as MapMetaData
    from .supported_types import NavSatFix as NavSatFix
    from .supported_types import OccupancyGrid as OccupancyGrid
    from .supported_types import Odometry as Odometry
    from .supported_types import Path as Path
    from .supported_types import Point as Point
    from .supported_types import PointCloud2 as PointCloud2
    from .supported_types import PointsOfInterest as PointsOfInterest
    from .supported_types import PointStamped as PointStamped
    from .supported_types import Pose as Pose
    from .supported_types import PoseArray as PoseArray
    from .supported_types import PoseStamped as PoseStamped
    from .supported_types import StreamingString as StreamingString
    from .supported_types import String as String
    from .supported_types import SupportedType as SupportedType
    from .supported_types import Trackings as Trackings
    from .supported_types import TrackingsMultiSource as TrackingsMultiSource
    from .supported_types import Twist as Twist
    from .supported_types import Video as Video
    from .supported_types import add_additional_datatypes as add_additional_datatypes
    from .topics import FixedInput as FixedInput
    from .topics import QoSConfig as QoSConfig
    from .topics import Topic as Topic
else:
    __getattr__, __dir__ = lazy_facade(__name__)
