"""Topic QoS -> ROS 2 QoS, and the Fast DDS shared-memory profile.

Mapping (see docs/ros2.md):

====================  ===========================================================
``QoSConfig``         ROS 2 ``QoSProfile``
====================  ===========================================================
``reliability``       ``RELIABLE`` / ``BEST_EFFORT``
``history``           ``KEEP_LAST`` / ``KEEP_ALL``
``depth``             ``depth`` of publishers; subscriptions use at least
                      :data:`READER_DEPTH_FLOOR` (see below)
``durability``        ``VOLATILE`` / ``TRANSIENT_LOCAL``
====================  ===========================================================

Why subscriptions get a deeper DDS queue than the topic asks for: the topic's depth is applied by
the shared :class:`~agents_core.transport.delivery.BoundedDelivery` (drop oldest, counted), the
same on every transport. If the DDS reader queue were as shallow, a burst would be dropped inside
DDS before the executor takes it, silently and uncounted. Depth is not part of ROS 2 QoS
compatibility, so this changes nothing for the publishers a subscription matches.
"""

from __future__ import annotations

import logging
import os
from importlib import resources

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from agents_core.topics import QoSConfig

__all__ = [
    "READER_DEPTH_FLOOR",
    "SHM_ENV_VAR",
    "enable_shared_memory_profile",
    "publisher_qos",
    "subscription_qos",
]

logger = logging.getLogger(__name__)

#: Smallest DDS history of a subscription (values beyond the topic's depth are dropped, and
#: counted, by the BoundedDelivery instead).
READER_DEPTH_FLOOR = 100

#: Set to ``0`` (or ``false`` / ``off`` / ``no``) to keep Fast DDS's own transports.
SHM_ENV_VAR = "AGENTS_ROS2_SHM"
#: The variable Fast DDS 2.x reads its default XML profile from.
FASTDDS_PROFILE_ENV_VAR = "FASTRTPS_DEFAULT_PROFILES_FILE"


def _qos(config: QoSConfig, depth: int) -> QoSProfile:
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST if config.history == "keep_last" else HistoryPolicy.KEEP_ALL,
        depth=depth,
        reliability=(ReliabilityPolicy.RELIABLE if config.reliability == "reliable"
                     else ReliabilityPolicy.BEST_EFFORT),
        durability=(DurabilityPolicy.TRANSIENT_LOCAL if config.durability == "transient_local"
                    else DurabilityPolicy.VOLATILE),
    )


def publisher_qos(config: QoSConfig) -> QoSProfile:
    """The ROS QoS of a publisher (its depth is also how many values a late subscriber gets replayed)."""
    return _qos(config, config.depth)


def subscription_qos(config: QoSConfig, depth_floor: int = READER_DEPTH_FLOOR) -> QoSProfile:
    """The ROS QoS of a subscription (depth at least ``depth_floor``; see the module docstring)."""
    return _qos(config, max(config.depth, depth_floor))


def shared_memory_wanted(option: bool | None) -> bool:
    """The ``shared_memory`` option if given, else :data:`SHM_ENV_VAR` (default on)."""
    if option is not None:
        return option
    return os.environ.get(SHM_ENV_VAR, "1").strip().lower() not in ("0", "false", "off", "no")


def enable_shared_memory_profile() -> bool:
    """Point Fast DDS at the 16 MB shared-memory profile unless the user chose a profile file.

    Fast DDS reads the variable once per process, when the first participant is created, so this
    only has an effect before the first ROS 2 context of the process is initialised. Returns
    whether the profile in use is ours.
    """
    ours = str(resources.files("agents_ros2").joinpath("fastdds_shm.xml"))
    current = os.environ.get(FASTDDS_PROFILE_ENV_VAR)
    if current is None:
        os.environ[FASTDDS_PROFILE_ENV_VAR] = ours
        return True
    if current != ours:
        logger.info("%s is set to %s; leaving the user's Fast DDS profile in place", FASTDDS_PROFILE_ENV_VAR,
                    current)
    return current == ours
