"""What the UI knows about a recipe: its components, their interfaces and actions, and its topics.

Two views answer the same questions:

- :class:`LocalRecipe`: the recipe runs in this process (``launcher.enable_ui``); the UI reads
  the :class:`~agents_core.components.component_base.Component` objects directly.
- :class:`RemoteRecipe`: the recipe runs elsewhere (another process or machine, on Zenoh or
  ROS 2); the UI finds its components with ``transport.discover()`` (or is given their names)
  and asks each one's ``<name>/describe`` service.

Everything that changes a component (transitions, actions) goes through the transport in both
cases, so the in-process UI exercises the same paths as an outside tool.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any, Protocol

from ..errors import AgentsError, ConfigError, RemoteError
from ..topics import Topic

if TYPE_CHECKING:
    from ..components.component_base import Component
    from ..transport.contract import Transport

__all__ = ["LocalRecipe", "RecipeView", "RemoteRecipe", "checked_description", "default_topics", "describe_local",
           "unavailable_entry"]

logger = logging.getLogger(__name__)


class RecipeView(Protocol):
    """The components a UI shows, described as ``<name>/describe`` replies are."""

    def component_names(self) -> list[str]:
        """The names of the recipe's components, sorted."""
        ...

    def describe(self, name: str) -> dict[str, Any]:
        """``{"name", "component_type", "run_type", "state", "health", "inputs", "outputs", "actions"}``.

        Raises :class:`KeyError` for a component the recipe does not have.
        """
        ...


def describe_local(component: Component) -> dict[str, Any]:
    """The describe reply of an in-process component (the same shape as its ``<name>/describe`` service)."""
    return {
        "name": component.component_name,
        "component_type": type(component).__name__,
        "run_type": component.run_type.value,
        "state": component.lifecycle_state.value,
        "health": component.health_status.name,
        "inputs": [{"name": t.name, "msg_type": t.msg_type.type_name()} for t in component.inputs],
        "outputs": [{"name": t.name, "msg_type": t.msg_type.type_name()} for t in component.outputs],
        "actions": component.available_actions(),
    }


class LocalRecipe:
    """The components of a recipe running in this process."""

    def __init__(self, components: Sequence[Component]) -> None:
        self._components = {c.component_name: c for c in components}

    def component_names(self) -> list[str]:
        return sorted(self._components)

    def describe(self, name: str) -> dict[str, Any]:
        return describe_local(self._components[name])

    def topics(self) -> dict[str, Topic]:
        """Every input and output topic of the recipe's components, by name (with their QoS)."""
        found: dict[str, Topic] = {}
        for c in self._components.values():
            for t in (*c.inputs, *c.outputs):
                found.setdefault(t.name, t)
        return found


class RemoteRecipe:
    """The components of a recipe running elsewhere, seen through ``transport``.

    :param names: the components to show; None finds them with ``transport.discover()``.
    :param timeout: seconds for each discovery and describe request.
    """

    def __init__(self, transport: Transport, names: Iterable[str] | None = None, timeout: float = 2.0) -> None:
        self._transport = transport
        self._names = sorted(set(names)) if names is not None else None
        self._timeout = timeout
        self._described: dict[str, dict[str, Any]] = {}

    def component_names(self) -> list[str]:
        if self._names is not None:
            return list(self._names)
        if not self._transport.capabilities.discovery:
            raise ConfigError(f"the {self._transport.name!r} transport cannot discover components: "
                              "name them (components=[...])")
        return sorted(self._transport.discover(timeout=self._timeout).components)

    def describe(self, name: str) -> dict[str, Any]:
        """``name``'s describe reply, checked (:func:`checked_description`): a malformed one raises RemoteError."""
        if self._names is not None and name not in self._names:
            raise KeyError(name)
        try:
            reply = checked_description(name, _describe_remote(self._transport, name, self._timeout))
        except (TypeError, ValueError, AttributeError) as exc:  # a reply of the wrong shape
            raise RemoteError(f"component {name!r} sent a describe reply that does not parse: {exc}") from None
        self._described[name] = reply
        return reply

    def last_description(self, name: str) -> dict[str, Any] | None:
        """The last describe reply of ``name`` (without asking again), or None."""
        return self._described.get(name)


def _describe_remote(transport: Transport, name: str, timeout: float) -> dict[str, Any]:
    from ..transport.graph import describe_component  # noqa: PLC0415  (attach mode only)

    return describe_component(transport, name, timeout=timeout)


def _topic_entries(name: str, reply: dict[str, Any], key: str) -> list[dict[str, str]]:
    entries = reply.get(key)
    if not isinstance(entries, list):
        raise RemoteError(f"component {name!r}: {key!r} of its describe reply is not a list")
    for entry in entries:
        if not (isinstance(entry, dict) and isinstance(entry.get("name"), str)
                and isinstance(entry.get("msg_type"), str)):
            raise RemoteError(f"component {name!r}: an entry of {key!r} is not {{'name': str, 'msg_type': str}}")
    return [{"name": e["name"], "msg_type": e["msg_type"]} for e in entries]


def checked_description(name: str, reply: Any) -> dict[str, Any]:
    """``reply`` if it has the shape of a describe reply (the UI reads its inputs, outputs and actions),
    else :class:`~agents_core.errors.RemoteError` saying what is wrong.

    A component on the network may run another version, or be something else answering on
    ``<name>/describe``: its reply is checked before anything is built from it.
    """
    if not isinstance(reply, dict):
        raise RemoteError(f"component {name!r} sent a describe reply that is a {type(reply).__name__}, not a mapping")
    checked = dict(reply)
    checked["inputs"] = _topic_entries(name, reply, "inputs")
    checked["outputs"] = _topic_entries(name, reply, "outputs")
    actions = reply.get("actions", {})
    if not isinstance(actions, dict) or not all(isinstance(k, str) and isinstance(v, dict) for k, v in actions.items()):
        raise RemoteError(f"component {name!r}: 'actions' of its describe reply is not a mapping of descriptions")
    for key in ("state", "health", "component_type", "run_type"):
        if key in checked and not isinstance(checked[key], str):
            checked[key] = str(checked[key])[:100]
    return checked


def unavailable_entry(name: str, reason: str) -> dict[str, Any]:
    """What the UI shows for a component whose description could not be had: no topics, no actions."""
    return {"name": name, "state": "unavailable", "health": "unknown", "error": reason[:500],
            "inputs": [], "outputs": [], "actions": {}}


def topic_from_description(entry: dict[str, Any]) -> Topic | None:
    """A Topic for a describe reply's ``{"name", "msg_type"}``, or None for a type this process lacks."""
    try:
        return Topic(str(entry["name"]), str(entry["msg_type"]))
    except (AgentsError, KeyError) as exc:
        logger.warning("topic %r is left out of the UI: %s", entry.get("name"), exc)
        return None


def default_topics(descriptions: Iterable[dict[str, Any]]) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """What a UI shows when not told: (inputs, outputs).

    Outputs: every component output. Inputs: every component input that no component of the
    recipe publishes (what the outside world, here the UI, has to provide).
    """
    inputs: dict[str, dict[str, Any]] = {}
    outputs: dict[str, dict[str, Any]] = {}
    for d in descriptions:
        for entry in d.get("outputs", []):
            outputs.setdefault(entry["name"], entry)
        for entry in d.get("inputs", []):
            inputs.setdefault(entry["name"], entry)
    return [e for n, e in sorted(inputs.items()) if n not in outputs], [e for _, e in sorted(outputs.items())]
