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

from ._lazy import lazy_facade
from .types.component_status import ComponentStatusMsg
from .types.fields import MAX_ARRAY_DIM, Header, Wire, as_numeric_array, values_equal, wire

if TYPE_CHECKING:
    from .types.geometry import OdometryMsg, PathMsg, PointMsg, PoseArrayMsg, PoseMsg, TwistMsg
    from .types.joints import JointJogMsg, JointStateMsg, JointTrajectoryMsg, JointTrajectoryPointMsg
    from .types.maps import MapMetaDataMsg, OccupancyGridMsg
    from .types.media import (
        DEPTH_ENCODINGS,
        IMAGE_ENCODINGS,
        MAX_IMAGE_SIDE,
        AudioMsg,
        CompressedImageMsg,
        ImageMsg,
        RGBDMsg,
        VideoMsg,
        image_array,
    )
    from .types.perception import DetectionsMsg, PointsOfInterestMsg, TrackingsMsg
    from .types.sensors import POINT_FIELD_DTYPES, CameraInfoMsg, ImuMsg, LaserScanMsg, NavSatFixMsg, PointCloud2Msg
    from .types.text import StreamingStringMsg
else:
    __getattr__, __dir__ = lazy_facade(__name__)

__all__ = [
    "DEPTH_ENCODINGS",
    "IMAGE_ENCODINGS",
    "MAX_ARRAY_DIM",
    "MAX_IMAGE_SIDE",
    "POINT_FIELD_DTYPES",
    "AudioMsg",
    "CameraInfoMsg",
    "ComponentStatusMsg",
    "CompressedImageMsg",
    "DetectionsMsg",
    "Header",
    "ImageMsg",
    "ImuMsg",
    "JointJogMsg",
    "JointStateMsg",
    "JointTrajectoryMsg",
    "JointTrajectoryPointMsg",
    "LaserScanMsg",
    "MapMetaDataMsg",
    "NavSatFixMsg",
    "OccupancyGridMsg",
    "OdometryMsg",
    "PathMsg",
    "PointCloud2Msg",
    "PointMsg",
    "PointsOfInterestMsg",
    "PoseArrayMsg",
    "PoseMsg",
    "RGBDMsg",
    "StreamingStringMsg",
    "TrackingsMsg",
    "TwistMsg",
    "VideoMsg",
    "Wire",
    "as_numeric_array",
    "image_array",
    "values_equal",
    "wire",
]
