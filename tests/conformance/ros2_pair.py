"""Two ROS 2 transports in this process that reach each other on loopback.

Used by the conformance suite (see conftest.py). Each transport has a ROS context (a DDS
participant) of its own, so ``a`` and ``b`` discover each other as two processes would. Discovery
stays on this host (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) and in a ROS domain derived from
the PID, so parallel runs (and any robot on the network) never meet.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

from agents_ros2.transport import Ros2Transport


def private_ros_environment() -> int:
    """Keep ROS 2 discovery on this host, in a domain of this process's own; returns the domain id.

    Must run before the first ROS context of the process is initialised (rcl reads both there).
    """
    domain_id = 1 + os.getpid() % 100
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ["ROS_DOMAIN_ID"] = str(domain_id)
    return domain_id


@contextlib.contextmanager
def ros2_pair() -> Iterator[tuple[Ros2Transport, Ros2Transport]]:
    """Yield ``(a, b)``: two transports with a DDS participant each; both closed on exit."""
    domain_id = private_ros_environment()
    a = Ros2Transport(domain_id=domain_id)
    try:
        b = Ros2Transport(domain_id=domain_id)
    except BaseException:
        a.close()
        raise
    try:
        yield a, b
    finally:
        b.close()
        a.close()
