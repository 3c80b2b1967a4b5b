"""Namespaces: one recipe run many times side by side (a fleet of robots), as ROS 2 namespaces do it.

``Launcher(namespace="robot1")`` runs its recipe on a *namespaced view* of the transport
(:func:`namespaced`). Inside the recipe nothing changes: its components keep their names
(``arm``), their topics theirs (``camera``). On the wire, and for every other process, names
are resolved the way ROS 2 resolves a node's names in a namespace:

=======================  =====================  ==================================================
in the recipe            on the wire            why
=======================  =====================  ==================================================
component ``arm``        ``robot1/arm``         its node: ``arm`` in namespace ``/robot1`` on ROS 2
topic ``camera``         ``robot1/camera``      relative: under the namespace
topic ``/map``           ``map``                absolute: shared by every robot (and the operator)
``arm/status``,          ``robot1/arm/status``, a component's own topics and services (status,
``arm/execute_method``   ...                    lifecycle, ``execute_method``, ``describe``,
                                                goals) follow its name
=======================  =====================  ==================================================

So two robots started from one recipe under ``robot1`` and ``robot2`` never collide, and one
operator (a recipe without a namespace, or ``agentsctl``) sees ``robot1/arm`` and ``robot2/arm``
and addresses each (``agentsctl call robot1/arm <method>``). The view works on every transport:
it maps names before they reach the driver (memory, Zenoh, ROS 2, a third party's); on ROS 2
the component's node gets the real node namespace (the driver splits ``robot1/arm`` into
namespace ``/robot1`` and node ``arm``). :meth:`~agents_core.transport.core.DriverTransport.discover`
on a view shows the whole graph, as ``ros2 topic list`` does in a namespaced shell; a component's
``describe`` reply (``agentsctl components status``, ``agentsctl ui``) gives its wire names.

A namespace is one or more ``/``-separated chunks of letters, digits and ``_`` (a leading or
trailing ``/`` is dropped): :func:`validate_namespace` says what is wrong, naming the field.
"""

from __future__ import annotations

import os
from typing import Any

import attrs

from ..errors import ConfigError, TopicNameError
from ..topics import Topic, validate_topic_name
from .core import DriverTransport
from .driver import (
    DriverActionServer,
    DriverGoal,
    DriverPresence,
    DriverPublisher,
    GoalEvents,
    GoalServerHooks,
    Lane,
    ServiceHandler,
    Sink,
    TransitionHandler,
)
from .goals import ActionType
from .graph import Graph

__all__ = ["NAMESPACE_ENV_VAR", "NamespacedDriver", "namespace_from_env", "namespaced", "resolve_name",
           "validate_namespace", "wire_description"]

#: Read by ``Launcher()`` when no ``namespace=`` is given (set by ``agentsctl run --namespace``).
NAMESPACE_ENV_VAR = "AGENTS_NAMESPACE"


def validate_namespace(value: Any, field: str = "namespace") -> str:
    """``value`` as a namespace (``"robot1"``, ``"site_a/robot1"``; ``""`` for none); ConfigError naming ``field``."""
    if value is None:
        return ""
    if not isinstance(value, str):
        raise ConfigError(f"{field} must be a str such as 'robot1', got {type(value).__name__}")
    stripped = value.strip().strip("/")
    if not stripped:
        return ""
    try:
        validate_topic_name(stripped, field)
    except TopicNameError as exc:
        raise ConfigError(f"{field} {value!r} is not a namespace: {exc}") from None
    if any(chunk.startswith("@") for chunk in stripped.split("/")):  # pragma: no cover - the name rules refuse it
        raise ConfigError(f"{field} {value!r}: a chunk may not start with '@'")
    return stripped


def namespace_from_env() -> str:
    """``AGENTS_NAMESPACE`` as a namespace (``""`` when unset)."""
    return validate_namespace(os.environ.get(NAMESPACE_ENV_VAR, ""), NAMESPACE_ENV_VAR)


def resolve_name(namespace: str, name: str) -> str:
    """The wire name of ``name`` in ``namespace``: relative ones go under it, absolute ones (``/map``) stay shared."""
    if name.startswith("/"):
        return name.lstrip("/")
    return f"{namespace}/{name}" if namespace else name


def wire_description(namespace: str, reply: Any) -> Any:
    """A component's ``describe`` reply with its name and its topics' names as observers must use them (wire names)."""
    if not isinstance(reply, dict):
        return reply
    described = dict(reply)
    if isinstance(described.get("name"), str):
        described["name"] = resolve_name(namespace, described["name"])
    for key in ("inputs", "outputs"):
        if isinstance(described.get(key), list):
            described[key] = [{**t, "name": resolve_name(namespace, t["name"])}
                              if isinstance(t, dict) and isinstance(t.get("name"), str) else t
                              for t in described[key]]
    return described


class NamespacedDriver:
    """A driver that resolves every name in a namespace (:func:`resolve_name`) before the inner driver sees it.

    It shares the inner transport's driver (one session, one node set); closing it closes the
    inner transport only when ``owns_inner`` says the view is its only user.
    """

    def __init__(self, inner: DriverTransport, namespace: str, *, owns_inner: bool) -> None:
        self._inner = inner
        self._driver: Any = inner.driver
        self.namespace = validate_namespace(namespace)
        self._owns_inner = owns_inner
        self.name = inner.name
        self.cross_process = inner.capabilities.cross_process
        self.discovery_settle_s = inner.capabilities.discovery_settle_s
        self.local_requests = inner.capabilities.local_requests
        self.validates_incoming = inner.capabilities.validates_incoming

    def _name(self, name: str) -> str:
        return resolve_name(self.namespace, name)

    def _owner(self, owner: str | None) -> str | None:
        return None if owner is None else self._name(owner)

    def _topic(self, topic: Topic) -> Topic:
        return attrs.evolve(topic, name=self._name(topic.name))

    def open_publisher(self, topic: Topic, owner: str | None) -> DriverPublisher:
        """The inner driver's publisher on the topic's wire name."""
        publisher: DriverPublisher = self._driver.open_publisher(self._topic(topic), self._owner(owner))
        return publisher

    def open_subscriber(self, topic: Topic, sink: Sink, owner: str | None) -> Any:
        """The inner driver's subscriber on the topic's wire name."""
        return self._driver.open_subscriber(self._topic(topic), sink, self._owner(owner))

    def serve(self, name: str, handler: ServiceHandler, owner: str | None, lane: Lane) -> Any:
        """Serve the service's wire name; a component's ``describe`` answers in wire names (see wire_description)."""
        if owner is not None and name == f"{owner}/describe":
            inner = handler

            def handler(request: dict[str, Any]) -> dict[str, Any]:
                described: dict[str, Any] = wire_description(self.namespace, inner(request))
                return described
        return self._driver.serve(self._name(name), handler, self._owner(owner), lane)

    def call(self, name: str, payload: dict[str, Any], timeout: float) -> dict[str, Any]:
        """Call the service's wire name."""
        reply: dict[str, Any] = self._driver.call(self._name(name), payload, timeout)
        return reply

    def declare_presence(self, name: str, on_transition: TransitionHandler, lane: Lane) -> DriverPresence:
        """Declare the component under its wire name (on ROS 2: its node in the namespace)."""
        presence: DriverPresence = self._driver.declare_presence(self._name(name), on_transition, lane)
        return presence

    def read_state(self, name: str, timeout: float) -> Any:
        """The state of the component with this name in the namespace."""
        return self._driver.read_state(self._name(name), timeout)

    def request_transition(self, name: str, transition: str, timeout: float) -> bool:
        """Ask the component with this name in the namespace for a transition."""
        return bool(self._driver.request_transition(self._name(name), transition, timeout))

    def discover(self, timeout: float) -> Graph:
        """The whole graph (every namespace), with wire names."""
        graph: Graph = self._driver.discover(timeout)
        return graph

    def serve_goals(self, name: str, definition: ActionType, hooks: GoalServerHooks, owner: str | None,
                    lane: Lane) -> DriverActionServer:
        """Serve the action's wire name."""
        server: DriverActionServer = self._driver.serve_goals(self._name(name), definition, hooks,
                                                              self._owner(owner), lane)
        return server

    def send_goal(self, name: str, definition: ActionType, goal_id: str, goal: dict[str, Any],
                  events: GoalEvents, timeout: float) -> DriverGoal:
        """Send a goal to the action's wire name."""
        handle: DriverGoal = self._driver.send_goal(self._name(name), definition, goal_id, goal, events, timeout)
        return handle

    def peer_process_options(self) -> dict[str, Any]:
        """The inner driver's: a component process opens the same transport, then its own view."""
        options: dict[str, Any] = self._driver.peer_process_options()
        return options

    def close(self) -> None:
        """Close the inner transport when this view owns it; else leave it to its owner."""
        if self._owns_inner:
            self._inner.close()

    def __getattr__(self, name: str) -> Any:
        # What a middleware's driver offers beyond the primitives (Zenoh's config, ...), for describing it.
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self._driver, name)

    def __repr__(self) -> str:
        return f"<NamespacedDriver {self.namespace!r} over {self._driver!r}>"


def namespaced(transport: DriverTransport, namespace: str, *, owns_inner: bool = False) -> DriverTransport:
    """A view of ``transport`` whose names resolve in ``namespace`` (see the module docstring); ``transport``
    itself when the namespace is empty. ``owns_inner``: closing the view closes ``transport`` too."""
    namespace = validate_namespace(namespace)
    if not namespace:
        return transport
    view = DriverTransport(NamespacedDriver(transport, namespace, owns_inner=owns_inner))
    view.capabilities = transport.capabilities
    return view
