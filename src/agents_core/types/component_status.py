"""The framework's own message: a component's lifecycle state and health, as published on its status topic."""

from __future__ import annotations

from typing import Any

from attrs import define, field

from .base import SupportedType
from .fields import Header, Message, header_field, is_str, named, wire

__all__ = ["ComponentStatus", "ComponentStatusMsg"]


@named
@define(eq=False)
class ComponentStatusMsg(Message):
    """A component's lifecycle state and health, as published on its status topic.

    ``health`` is one of the :class:`~agents_core.status.HealthStatus` names
    (``"HEALTHY"``, ``"ALGORITHM_FAILURE"``, ``"COMPONENT_FAILURE"``, ``"SYSTEM_FAILURE"``).
    """

    component: str = field(validator=is_str)
    lifecycle_state: str = field(default="unconfigured", validator=is_str)
    health: str = field(default="HEALTHY", validator=is_str, metadata=wire("str (HEALTHY, ALGORITHM_FAILURE, ...)"))
    message: str = field(default="", validator=is_str)
    #: The runtime's figures as compact JSON (``agentsctl top``; :mod:`agents_core.runtime.figures`);
    #: empty when not reported (a ROS 2 status carries none).
    stats: str = field(default="", validator=is_str, metadata=wire("str (JSON: steps, rate_hz, p50_ms, ...)"))
    header: Header = header_field()


class ComponentStatus(SupportedType):
    """A component's lifecycle state and health (:class:`~agents_core.messages.ComponentStatusMsg`)."""

    value_class = ComponentStatusMsg

    @classmethod
    def example(cls) -> Any:
        return ComponentStatusMsg(component="llm", lifecycle_state="active", health="HEALTHY")
