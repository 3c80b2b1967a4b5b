"""Value classes: the plain Python form of every message that flows between components.

Simple types travel as builtins (``str``, ``bool``, ``int``, ``float``) or numpy arrays. Structured
types are small attrs classes, each with a :class:`Header` (stamp and frame_id) that transport
conversions preserve end to end. Constructing a value validates it and raises
:class:`~agents_core.errors.TypeValidationError` naming the field that is wrong.

Values are delivered zero-copy on the memory transport: every subscriber receives the same
object, so treat received values (and their numpy arrays) as read-only.

The classes live in :mod:`agents_core.types`, each in its family's module beside its type
(``ImageMsg`` in :mod:`agents_core.types.media`); this module re-exports them all (each family's at its
first access).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .support.lazy import lazy_facade
from .types.component_status import ComponentStatusMsg as ComponentStatusMsg
from .types.fields import MAX_ARRAY_DIM as MAX_ARRAY_DIM
from .types.fields import Header as Header
from .types.fields import Wire as Wire
from .types.fields import as_numeric_array as as_numeric_array
from .types.fields import values_equal as values_equal
from .types.fields import wire as wire

if TYPE_CHECKING:
    from .types.geometry import OdometryMsg as OdometryMsg
    from .types.geometry import PathMsg as PathMsg
    from .types.geometry import PointMsg as PointMsg
    from .types.geometry import PoseArrayMsg as PoseArrayMsg
    from .types.geometry import PoseMsg as PoseMsg
    from .types.geometry import TwistMsg as TwistMsg
    from .types.joints import JointJogMsg as JointJogMsg
    from .types.joints import JointStateMsg as JointStateMsg
    from .types.joints import JointTrajectoryMsg as JointTrajectoryMsg
    from .types.joints import JointTrajectoryPointMsg as JointTrajectoryPointMsg
    from .types.maps import MapMetaDataMsg as MapMetaDataMsg
    from .types.maps import OccupancyGridMsg as OccupancyGridMsg
    from .types.media import DEPTH_ENCODINGS as DEPTH_ENCODINGS
    from .types.media import IMAGE_ENCODINGS as IMAGE_ENCODINGS
    from .types.media import MAX_IMAGE_SIDE as MAX_IMAGE_SIDE
    from .types.media import AudioMsg as AudioMsg
    from .types.media import CompressedImageMsg as CompressedImageMsg
    from .types.media import ImageMsg as ImageMsg
    from .types.media import RGBDMsg as RGBDMsg
    from .types.media import VideoMsg as VideoMsg
    from .types.media import image_array as image_array
    from .types.perception import DetectionsMsg as DetectionsMsg
    from .types.perception import PointsOfInterestMsg as PointsOfInterestMsg
    from .types.perception import TrackingsMsg as TrackingsMsg
    from .types.sensors import POINT_FIELD_DTYPES as POINT_FIELD_DTYPES
    from .types.sensors import CameraInfoMsg as CameraInfoMsg
    from .types.sensors import ImuMsg as ImuMsg
    from .types.sensors import LaserScanMsg as LaserScanMsg
    from .types.sensors import NavSatFixMsg as NavSatFixMsg
    from .types.sensors import PointCloud2Msg as PointCloud2Msg
    from .types.text import StreamingStringMsg as StreamingStringMsg
else:
    __getattr__, __dir__ = lazy_facade(__name__)
