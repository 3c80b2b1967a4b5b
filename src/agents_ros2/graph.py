"""Graph discovery on ROS 2: the rclpy graph API, which sees plain ROS nodes as well as ours.

Topics come from ``get_topic_names_and_types``; each ROS type with an agents_core conversion is
shown under its agents_core type name (``std_msgs/msg/String`` -> ``String``), any other under
its ROS type string. Publishers and subscribers are counted per topic, leaving out the
discovering transport's own node (so an observer does not count itself). Components are the
nodes that serve ``<name>/describe`` with the ``agents_interfaces/srv/JsonCall`` type, which
every agents_core component does.

DDS discovery is asynchronous: a participant that has just started learns about the others over
0.1-2 s. :func:`discover_graph` therefore polls until the graph has stopped changing for a short
while (once another node has been seen), or until its timeout.
"""

from __future__ import annotations

import time
from typing import Any

from agents_core.transport.graph import Graph, TopicInfo

from .conversions import registered_conversions

__all__ = ["core_type_names", "discover_graph", "ros_type_string"]

#: The ROS service type every agents_core component's services have.
JSON_CALL_TYPE = "agents_interfaces/srv/JsonCall"
#: How long the graph must stay unchanged before discovery is taken to have settled.
_SETTLE_S = 0.3
_POLL_S = 0.05


def ros_type_string(ros_type: type[Any]) -> str:
    """``sensor_msgs.msg.Image`` -> ``"sensor_msgs/msg/Image"`` (the form the ROS graph reports)."""
    return f"{ros_type.__module__.split('.')[0]}/msg/{ros_type.__name__}"


def core_type_names() -> dict[str, str]:
    """ROS type string -> agents_core type name, for every registered conversion."""
    names: dict[str, str] = {}
    for type_name, conversion in registered_conversions().items():
        names.setdefault(ros_type_string(conversion.ros_type), type_name)
    return names


def _snapshot(node: Any) -> tuple[tuple[tuple[str, tuple[str, ...]], ...], tuple[str, ...]]:
    topics = tuple(sorted((name, tuple(types)) for name, types in node.get_topic_names_and_types()))
    nodes = tuple(sorted(f"{ns.rstrip('/')}/{n}" for n, ns in node.get_node_names_and_namespaces()))
    return topics, nodes


def _wait_for_settled_graph(node: Any, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    own = f"{node.get_namespace().rstrip('/')}/{node.get_name()}"
    last = _snapshot(node)
    stable_since = time.monotonic()
    while time.monotonic() < deadline:
        others = [n for n in last[1] if n != own]
        if others and time.monotonic() - stable_since >= _SETTLE_S:
            return
        time.sleep(_POLL_S)
        current = _snapshot(node)
        if current != last:
            last, stable_since = current, time.monotonic()


def discover_graph(node: Any, timeout: float) -> Graph:
    """The ROS graph as ``node`` sees it (see the module docstring), waiting at most ``timeout`` s."""
    _wait_for_settled_graph(node, timeout)
    names = core_type_names()
    topics: list[TopicInfo] = []
    for name, types in node.get_topic_names_and_types():
        publishers = node.count_publishers(name)
        subscribers = node.count_subscribers(name)
        for ros_type in types:
            topics.append(TopicInfo(name=name.lstrip("/"), msg_type=names.get(ros_type, ros_type),
                                    publishers=publishers, subscribers=subscribers))
    return Graph(topics=topics, components=_components(node))


def _components(node: Any) -> list[str]:
    # Per node: the graph-wide service list also holds clients (a caller of describe is no component).
    found: list[str] = []
    for node_name, namespace in node.get_node_names_and_namespaces():
        try:
            services = node.get_service_names_and_types_by_node(node_name, namespace)
        except Exception:  # the node left between the two graph queries
            continue
        found.extend(service[: -len("/describe")].lstrip("/") for service, types in services
                     if service.endswith("/describe") and JSON_CALL_TYPE in types)
    return found
