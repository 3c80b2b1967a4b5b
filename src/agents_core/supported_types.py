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

from .support.lazy import lazy_facade
from .types.base import SupportedType as SupportedType
from .types.base import _registry  # noqa: F401 - tests and plugins undo their registrations through it
from .types.base import add_additional_datatypes as add_additional_datatypes
from .types.base import check_ros_message as check_ros_message
from .types.base import get_type as get_type
from .types.base import registered_types as registered_types
from .types.base import ros_message_class as ros_message_class
from .types.base import shares_value_class as shares_value_class

if TYPE_CHECKING:
    from .types.component_status import ComponentStatus as ComponentStatus
    from .types.geometry import Odometry as Odometry
    from .types.geometry import Path as Path
    from .types.geometry import Point as Point
    from .types.geometry import PointStamped as PointStamped
    from .types.geometry import Pose as Pose
    from .types.geometry import PoseArray as PoseArray
    from .types.geometry import PoseStamped as PoseStamped
    from .types.geometry import Twist as Twist
    from .types.joints import JointJog as JointJog
    from .types.joints import JointState as JointState
    from .types.joints import JointTrajectory as JointTrajectory
    from .types.joints import JointTrajectoryPoint as JointTrajectoryPoint
    from .types.maps import MapMetaData as MapMetaData
    from .types.maps import OccupancyGrid as OccupancyGrid
    from .types.media import RGBD as RGBD
    from .types.media import Audio as Audio
    from .types.media import CompressedImage as CompressedImage
    from .types.media import Image as Image
    from .types.media import Video as Video
    from .types.perception import Detections as Detections
    from .types.perception import DetectionsMultiSource as DetectionsMultiSource
    from .types.perception import PointsOfInterest as PointsOfInterest
    from .types.perception import Trackings as Trackings
    from .types.perception import TrackingsMultiSource as TrackingsMultiSource
    from .types.scalars import Bool as Bool
    from .types.scalars import Float32 as Float32
    from .types.scalars import Float32MultiArray as Float32MultiArray
    from .types.scalars import Float64 as Float64
    from .types.scalars import Float64MultiArray as Float64MultiArray
    from .types.scalars import Int32 as Int32
    from .types.scalars import Int64 as Int64
    from .types.sensors import CameraInfo as CameraInfo
    from .types.sensors import Imu as Imu
    from .types.sensors import LaserScan as LaserScan
    from .types.sensors import NavSatFix as NavSatFix
    from .types.sensors import PointCloud2 as PointCloud2
    from .types.text import StreamingString as StreamingString
    from .types.text import String as String
else:
    __getattr__, __dir__ = lazy_facade(__name__)
