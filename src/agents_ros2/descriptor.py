"""The ROS 2 transport, described for the core (:class:`~agents_core.transport.descriptor.TransportDescriptor`).

Importing this module does not import ``rclpy``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

from agents_core.transport.descriptor import TransportDescriptor

__all__ = ["DESCRIPTOR", "describe", "isolate"]


def _domain(driver: Any) -> str:
    try:
        return str(driver.node.context.get_domain_id())
    except Exception:  # an older rclpy, or a driver without a node: the environment says the same
        return os.environ.get("ROS_DOMAIN_ID", "0") or "0"


def _discovery_range() -> str:
    value = os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").strip()
    if value:
        return value
    return "LOCALHOST" if os.environ.get("ROS_LOCALHOST_ONLY", "") == "1" else "SUBNET"


def describe(transport: Any) -> str:
    """The domain id and the discovery range of an open ROS 2 transport."""
    return f"domain {_domain(getattr(transport, 'driver', None))}; discovery range {_discovery_range()}"


def isolate() -> dict[str, Any]:
    """Keep ROS 2 on this host, in a domain of this process's own (in ``os.environ``); the options that use it."""
    from agents_core.testing.pairs import private_ros_environment  # noqa: PLC0415 - tests only

    return {"domain_id": private_ros_environment()}


def _observer_options(connect: Sequence[str] | None, mode: str | None) -> dict[str, Any]:
    return {}


#: The ROS 2 transport (``Launcher(transport="ros2")``).
DESCRIPTOR = TransportDescriptor(
    name="ros2", factory="agents_ros2.transport:Ros2Transport", title="ROS 2", extra="ros2",
    requires=("rclpy",),
    carries=frozenset({"values", "requests", "goals", "discovery", "cross-process", "attach"}),
    observer_options=_observer_options, isolate=isolate, describe=describe)
