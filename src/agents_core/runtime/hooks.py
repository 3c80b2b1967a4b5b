"""What the runtime needs of a component: :class:`ComponentHooks`, the one way it calls the component.

:class:`~agents_core.components.component_base.Component` satisfies it; the runtime never imports
the component classes, so a runtime change cannot reach into a component's state, and a
component's declaration can change without touching the runtime.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    from ..callbacks import GenericCallback
    from ..config import BaseComponentConfig
    from ..topics import Topic
    from ..transport.contract import Publisher
    from ..transport.goals import GoalHandle
    from .run_type import ComponentRunType

__all__ = ["ComponentHooks", "OutputSlot"]


class OutputSlot(Protocol):
    """A component's output, which the runtime connects to a transport publisher while active."""

    def attach(self, publisher: Publisher) -> None:
        """Publish through ``publisher`` from now on (at activate)."""
        ...

    def detach(self) -> None:
        """Close the transport publisher (at deactivate)."""
        ...


class ComponentHooks(Protocol):
    """The declaration and hooks of a component, as its runtime uses them."""

    component_name: str
    config: BaseComponentConfig
    inputs: list[Topic]
    outputs: list[Topic]
    trigger: Any
    run_type: ComponentRunType
    callbacks: dict[str, GenericCallback]
    trig_callbacks: dict[str, GenericCallback]
    _action_type: str | None

    @property
    def publishers_dict(self) -> Mapping[str, OutputSlot]:
        """The outputs by topic name."""
        ...

    @property
    def action_name(self) -> str:
        """Where an action-server component serves its goals."""
        ...

    def get_logger(self) -> logging.Logger:
        """The component's logger."""
        ...

    def component_description(self) -> dict[str, Any]:
        """What ``<name>/describe`` answers."""
        ...

    def available_actions(self) -> dict[str, dict[str, Any]]:
        """The ``@component_action`` methods and their descriptions."""
        ...

    def _execution_step(self, **kwargs: Any) -> None:
        """One step."""
        ...

    def activate_all_triggers(self) -> None:
        """Start the triggers (at activate; calls ``runtime.start_triggers()``)."""
        ...

    def main_action_callback(self, goal_handle: GoalHandle) -> dict[str, Any]:
        """Run one goal."""
        ...

    def _accept_goal(self, goal: dict[str, Any]) -> bool:
        """Whether to accept a goal."""
        ...

    # The transitions as the component exposes them (a transition asked from outside runs these,
    # so a subclass that extends one is honoured), and the hooks each runs inside.
    def configure(self) -> None: ...
    def activate(self) -> None: ...
    def deactivate(self) -> None: ...
    def cleanup(self) -> None: ...
    def shutdown(self) -> None: ...
    def custom_on_configure(self) -> None: ...
    def custom_on_activate(self) -> None: ...
    def custom_on_deactivate(self) -> None: ...
    def custom_on_cleanup(self) -> None: ...
    def custom_on_shutdown(self) -> None: ...

