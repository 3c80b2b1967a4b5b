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

The conversions are grouped by the families of the core's types, one module each: :mod:`.text`
(strings), :mod:`.scalars` (numbers, multi-arrays), :mod:`.media` (images, audio, video, RGBD),
:mod:`.perception` (detections, trackings, points of interest), :mod:`.geometry` (points, poses,
twists, odometry, paths), :mod:`.joints` (joint states, trajectories, jogs), :mod:`.maps`
(occupancy grids, map metadata), :mod:`.sensors` (laser scans, point clouds, IMU, satellite
fixes, camera info) and :mod:`.component_status`; :mod:`.base` holds what they share,
:mod:`.registry` the table and :mod:`.derive` the conversions derived from a ``_ros_type``.
To add a built-in conversion: put it in its family's ``CONVERSIONS``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from agents_core.support.lazy import lazy_facade
from agents_core.supported_types import registered_types

from . import component_status, geometry, joints, maps, media, perception, scalars, sensors, text
from .base import RosConversion as RosConversion
from .derive import derive_conversion as derive_conversion
from .registry import MissingConversionError as MissingConversionError
from .registry import (
    _conversions,  # noqa: F401  # the table itself, for tests that unregister what they registered
    register_builtin,
)
from .registry import conversion_for as conversion_for
from .registry import from_ros as from_ros
from .registry import register_conversion as register_conversion
from .registry import registered_conversions as registered_conversions
from .registry import to_ros as to_ros

if not TYPE_CHECKING:
    __getattr__, __dir__ = lazy_facade(__name__)


def _builtin_table() -> dict[str, RosConversion]:
    """Every family's built-in conversions, in the order the core registered the types.

    The core's order predates the families, so registered_conversions() lists the types as the
    core's registry does; a conversion for a type the core does not know (none today) comes last.
    """
    families = (text, scalars, media, perception, geometry, joints, maps, sensors, component_status)
    table = {name: c for family in families for name, c in family.CONVERSIONS.items()}
    order = [name for name in registered_types() if name in table]
    order += [name for name in table if name not in order]
    return {name: table[name] for name in order}


register_builtin(_builtin_table())
