"""ROS 2 without rclpy: the ``rmw_zenoh`` transport, in rmw_zenoh's own wire format (see ``docs/rmw-zenoh.md``).

:mod:`.wire` (keys, liveliness tokens, QoS strings, attachments, GIDs), :mod:`.typesupport` (definitions,
RIHS01 hashes and CDR from rosbags), :mod:`.codec` (the ``ros2`` transport's conversions plus CDR),
:mod:`.session`, :mod:`.entities`, :mod:`.discovery` and :mod:`.transport`.
"""

from __future__ import annotations

__all__: list[str] = []
