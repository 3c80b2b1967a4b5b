"""ROS 2 conversion of the framework's status: ``agents_interfaces/ComponentStatus``."""

from __future__ import annotations

from typing import Any

from agents_core import messages as m
from agents_core.errors import TypeValidationError
from agents_core.status import HealthStatus

from .base import RosConversion, ai, header_from_ros, header_to_ros

__all__ = ["CONVERSIONS"]


def _status_to_ros(v: m.ComponentStatusMsg) -> Any:
    try:
        health = HealthStatus[v.health]
    except KeyError:
        raise TypeValidationError(f"component status health {v.health!r} is not one of "
                                  f"{[h.name for h in HealthStatus]}") from None
    out = ai.ComponentStatus(component=v.component, lifecycle_state=v.lifecycle_state, health=int(health),
                             message=v.message)
    header_to_ros(v.header, out.header)
    return out


def _status_from_ros(msg: Any) -> m.ComponentStatusMsg:
    try:
        health = HealthStatus(msg.health).name
    except ValueError:
        raise TypeValidationError(f"component status health code {msg.health} is unknown") from None
    return m.ComponentStatusMsg(component=msg.component, lifecycle_state=msg.lifecycle_state, health=health,
                                message=msg.message, header=header_from_ros(msg.header))


#: The built-in conversions of this family.
CONVERSIONS: dict[str, RosConversion] = {
    "ComponentStatus": RosConversion(ai.ComponentStatus, _status_to_ros, _status_from_ros),
}
