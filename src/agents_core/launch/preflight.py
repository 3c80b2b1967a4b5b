"""Checks the launcher makes before it starts anything, and the launch file it reads.

Each refuses, with the component, event or file named, what would otherwise fail later in a
component process or be silently ignored.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from ..actions import Action
from ..components.component_base import Component
from ..config import load_config_file
from ..errors import ConfigError, WiringError
from ..events import Event

__all__ = ["LIFECYCLE_METHODS", "check_remote_action", "check_transferable",
           "read_launch_file", "refuse_inside_component_process"]


def check_transferable(components: Sequence[Component]) -> None:
    """Refuse at add_pkg what cannot reach a component process (a lambda given to a setup call, ...)."""
    from .spec import ComponentSpec  # noqa: PLC0415

    for c in components:
        ComponentSpec.from_component(c, "", {}, 0)


#: The lifecycle transitions an Action may call on a component in another process.
LIFECYCLE_METHODS = frozenset({"configure", "activate", "deactivate", "cleanup", "shutdown"})


def check_remote_action(event: Event, action: Action) -> None:
    """Refuse, at start, an action on a component process that its services cannot run."""
    owner = action.owner
    if not isinstance(owner, Component) or action.name in LIFECYCLE_METHODS:
        return
    if action.name not in owner.available_actions():
        raise WiringError(f"event {event.name!r}: action {action.name!r} of component {owner.component_name!r} "
                          "cannot run in the component's process: mark the method @component_action (it then "
                          "runs through the component's execute_method service)")


def refuse_inside_component_process() -> None:
    """A component process imports the recipe for its classes: the recipe's launcher must not launch again."""
    recipe_import = sys.modules.get("agents_core.launch.recipe_import")
    if recipe_import is not None and recipe_import.importing_recipe():
        raise recipe_import.RecipeImportStop


def read_launch_file(path: str) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
    """(transport section, component sections) of a launcher config file."""
    data = load_config_file(path)
    transport = data.pop("transport", {})
    if not isinstance(transport, dict):
        raise ConfigError(f"config file {path}: 'transport' must be a section (name and options)")
    name = transport.get("name")
    if name is not None and not isinstance(name, str):
        raise ConfigError(f"config file {path}: transport.name must be a str such as 'zenoh'")
    sections: dict[str, dict[str, Any]] = {}
    for key, value in data.items():
        if not isinstance(value, dict):
            raise ConfigError(f"config file {path}: {key!r} must be a section of config fields for the "
                              f"component of that name, got {type(value).__name__}")
        sections[key] = value
    return dict(transport), sections
