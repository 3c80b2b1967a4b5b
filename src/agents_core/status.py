"""Lifecycle states and health statuses of components.

The lifecycle follows the ROS 2 managed-node model, so the ROS 2 adapter maps it one to one and
other transports expose the same names::

    unconfigured --configure--> inactive --activate--> active
         ^                        |   ^                  |
         +------cleanup-----------+   +---deactivate-----+
    any --shutdown--> finalized        any --(failure)--> error
"""

from __future__ import annotations

import enum

__all__ = ["TRANSITIONS", "HealthStatus", "LifecycleState"]


class LifecycleState(str, enum.Enum):
    """Where a component is in its lifecycle (the values are the ROS 2 state labels)."""

    UNCONFIGURED = "unconfigured"
    INACTIVE = "inactive"
    ACTIVE = "active"
    FINALIZED = "finalized"
    ERROR = "errorprocessing"


class HealthStatus(enum.IntEnum):
    """How well a component is doing, published on its status topic.

    The order matters: a larger value is a more serious failure.
    """

    HEALTHY = 0
    ALGORITHM_FAILURE = 1
    COMPONENT_FAILURE = 2
    SYSTEM_FAILURE = 3

    def __str__(self) -> str:
        """The name (``print(component.health_status)`` says ``COMPONENT_FAILURE``, not ``2``)."""
        return self.name

    def __format__(self, spec: str) -> str:
        """The name in ``f"{status}"`` (``f"{status:>20}"`` too); a numeric type (``f"{status:d}"``): the number."""
        numeric = spec[-1:] in tuple("bcdeEfFgGnoxX%")
        return format(int(self), spec) if numeric else format(self.name, spec)


#: transition name -> (states it may start from, state it ends in)
TRANSITIONS: dict[str, tuple[frozenset[LifecycleState], LifecycleState]] = {
    "configure": (frozenset({LifecycleState.UNCONFIGURED}), LifecycleState.INACTIVE),
    "activate": (frozenset({LifecycleState.INACTIVE}), LifecycleState.ACTIVE),
    "deactivate": (frozenset({LifecycleState.ACTIVE}), LifecycleState.INACTIVE),
    "cleanup": (frozenset({LifecycleState.INACTIVE, LifecycleState.ERROR}), LifecycleState.UNCONFIGURED),
    "shutdown": (
        frozenset({LifecycleState.UNCONFIGURED, LifecycleState.INACTIVE, LifecycleState.ACTIVE,
                   LifecycleState.ERROR}),
        LifecycleState.FINALIZED,
    ),
}
