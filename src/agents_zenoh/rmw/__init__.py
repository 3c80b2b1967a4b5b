"""ROS 2 without rclpy: the ``rmw_zenoh`` transport, in rmw_zenoh's own wire format (see ``docs/rmw-zenoh.md``).

:mod:`.wire` (keys, liveliness tokens, QoS strings, attachments, GIDs), :mod:`.typesupport` (definitions,
RIHS01 hashes and CDR from rosbags), :mod:`.codec` (the ``ros2`` transport's conversions plus CDR),
:mod:`.session`, :mod:`.entities`, :mod:`.discovery` and :mod:`.transport`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from agents_core.support.lazy import lazy_facade

if not TYPE_CHECKING:  # nothing re-exported yet: __all__ is empty
    __getattr__, __dir__ = lazy_facade(__name__)
