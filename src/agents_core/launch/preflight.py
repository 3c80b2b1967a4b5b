"""Checks the launcher makes before it starts anything, and the launch file it reads.

Each refuses, with the component, event or file named, what would otherwise fail later in a
component process or be silently ignored.
"""

from __future__ import annotations

import difflib
import logging
import os
import sys
from collections.abc import Mapping, Sequence
from typing import Any

from ..actions import Action
from ..components.component_base import Component
from ..config import load_config_file
from ..errors import ConfigError, WiringError
from ..events import Event
from ..transport.registry import TRANSPORT_ENV_VAR
from .process_start import process_start as choose_process_start
from .recipe import RecipeSettings

__all__ = ["LIFECYCLE_METHODS", "apply_fail_action", "apply_launch_file", "check_remote_action", "check_transferable",
           "launch_settings", "read_launch_file", "refuse_inside_component_process"]

#: The launcher's logger: these checks speak for it.
logger = logging.getLogger("agents_core.launch.launcher")


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


def launch_settings(transport: Any, transport_options: Mapping[str, Any] | None, config_file: Any,
                    process_start: str | None) -> tuple[RecipeSettings, dict[str, dict[str, Any]]]:
    """The Launcher's constructor arguments, with the launch file's ``transport`` section, as recipe settings;
    and the file's component sections (applied at start). What is passed explicitly wins over the file."""
    try:
        start = choose_process_start(process_start)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    config = str(config_file) if config_file is not None else None
    file_transport: dict[str, Any] = {}
    sections: dict[str, dict[str, Any]] = {}
    if config is not None:
        file_transport, sections = read_launch_file(config)
    file_name = file_transport.pop("name", None)
    if transport is None and file_name is not None and not os.environ.get(TRANSPORT_ENV_VAR, "").strip():
        transport = file_name
    options = {**(file_transport if isinstance(transport, str | None) else {}), **dict(transport_options or {})}
    return RecipeSettings(transport=transport, transport_options=options, config_file=config,
                          process_start=start), sections


def apply_launch_file(components: Sequence[Component], sections: Mapping[str, Mapping[str, Any]],
                      config_file: str | None) -> None:
    """Apply each section of the launch file to the config of the component it names (refusing unknown names)."""
    names = [c.component_name for c in components]
    for name in sections:
        if name not in names:
            close = difflib.get_close_matches(name, names, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise ConfigError(f"config file {config_file}: section {name!r} names no component "
                              f"of this launcher{hint} (components: {names})")
    for c in components:
        section = sections.get(c.component_name)
        if section:
            try:
                c.config.update(**section)
            except ConfigError as exc:
                raise ConfigError(f"config file {config_file}, section {c.component_name!r}: {exc}") from exc


def apply_fail_action(components: Sequence[Component], fail_action: tuple[str, int | None] | None,
                      fallback_rate: float | None) -> None:
    """``Launcher.on_fail(action_name, max_retries)``: give each component that fallback (refusing a missing method)."""
    if fallback_rate is not None:
        logger.warning("fallback_rate=%g Hz is not a polling rate here: each fallback runs as soon as its "
                       "component reports the failure", fallback_rate)
    if fail_action is None:
        return
    action_name, max_retries = fail_action
    for c in components:
        method = getattr(c, action_name, None)
        if not callable(method):
            raise ConfigError(f"on_fail(action_name={action_name!r}): component {c.component_name!r} "
                              f"({type(c).__name__}) has no method {action_name!r}")
        c.on_fail(Action(method), max_retries)
