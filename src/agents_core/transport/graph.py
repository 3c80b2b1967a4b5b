"""Graph introspection: what topics and components a running system has, seen from one transport.

:meth:`DriverTransport.discover() <agents_core.transport.core.DriverTransport.discover>` returns a
:class:`Graph`: every topic with its message type and how many publishers and subscribers it has,
and the names of the live agents_core components. Drivers that can find this out implement the
optional :meth:`~agents_core.transport.driver.TransportDriver.discover` primitive (memory: its own
tables; Zenoh: liveliness tokens; ROS 2: the ROS graph, which also shows plain ROS nodes' topics).

:func:`describe_component` asks a component's ``<name>/describe`` service what it is: its type,
run type, lifecycle state, health, inputs, outputs and the actions callable through
``<name>/execute_method``.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any, Protocol

from attrs import define, field

from ..errors import RemoteError
from ..topics import validate_topic_name

__all__ = ["Graph", "Requester", "TopicInfo", "describe_component", "merge_topic_counts"]


class Requester(Protocol):
    """Anything that sends a request to a service and returns its reply (a transport does)."""

    def request(self, name: str, payload: dict[str, Any], *, timeout: float = 5.0) -> dict[str, Any]:
        """See :meth:`agents_core.transport.core.DriverTransport.request`."""
        ...


#: The keys every ``<name>/describe`` reply has.
DESCRIBE_KEYS = ("name", "component_type", "run_type", "state", "health", "inputs", "outputs", "actions")


@define(frozen=True, kw_only=True)
class TopicInfo:
    """One topic of the graph.

    :param name: the topic name as the core writes it (no leading ``/``).
    :param msg_type: the agents_core type name (``"String"``, ``"Image"``...), or, for a plain ROS
        topic whose ROS type has no agents_core conversion, the ROS type string
        (``"rcl_interfaces/msg/Log"``).
    :param publishers: how many publishers the transport sees on it.
    :param subscribers: how many subscribers.
    """

    name: str
    msg_type: str
    publishers: int = 0
    subscribers: int = 0

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready mapping with the field names as keys."""
        return {"name": self.name, "msg_type": self.msg_type, "publishers": self.publishers,
                "subscribers": self.subscribers}


def _sorted_topics(topics: Iterable[TopicInfo]) -> list[TopicInfo]:
    return sorted(topics, key=lambda t: (t.name, t.msg_type))


def _sorted_names(names: Iterable[str]) -> list[str]:
    return sorted(set(names))


@define(frozen=True, kw_only=True)
class Graph:
    """A snapshot of the topics and agents_core components a transport can see (sorted by name)."""

    topics: list[TopicInfo] = field(factory=list, converter=_sorted_topics)
    components: list[str] = field(factory=list, converter=_sorted_names)

    def topic(self, name: str) -> TopicInfo | None:
        """The topic called ``name`` (a leading ``/`` is ignored), or None if the graph has none."""
        wanted = name.lstrip("/")
        for info in self.topics:
            if info.name == wanted:
                return info
        return None

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready mapping: ``{"topics": [...], "components": [...]}``."""
        return {"topics": [t.to_dict() for t in self.topics], "components": list(self.components)}


def merge_topic_counts(entries: list[tuple[str, str, str]]) -> list[TopicInfo]:
    """Count ``(topic, msg_type, "pub" | "sub")`` entries into one :class:`TopicInfo` per topic and type."""
    counts: dict[tuple[str, str], list[int]] = {}
    for name, msg_type, role in entries:
        pair = counts.setdefault((name.lstrip("/"), msg_type), [0, 0])
        pair[0 if role == "pub" else 1] += 1
    return [TopicInfo(name=n, msg_type=t, publishers=p, subscribers=s) for (n, t), (p, s) in counts.items()]


def describe_component(transport: Requester, name: str, timeout: float = 2.0) -> dict[str, Any]:
    """Ask component ``name`` to describe itself through its ``<name>/describe`` service.

    Returns ``{"name", "component_type", "run_type", "state", "health", "inputs", "outputs",
    "actions"}`` (inputs/outputs: lists of ``{"name", "msg_type"}``; actions: method name ->
    OpenAI-style description). Raises the transport's request errors
    (:class:`~agents_core.errors.ServiceUnavailableError` when no such component answers,
    :class:`~agents_core.errors.RequestTimeoutError`), and
    :class:`~agents_core.errors.RemoteError` for a reply without those keys.
    """
    validate_topic_name(name, "component")
    reply = transport.request(f"{name.lstrip('/')}/describe", {}, timeout=timeout)
    missing = [k for k in DESCRIBE_KEYS if k not in reply]
    if missing:
        raise RemoteError(f"component {name!r} sent a describe reply without {missing}")
    return reply
