"""The rmw_zenoh transport, described for the core (imports neither ``zenoh`` nor ``rosbags``)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from agents_core.transport.descriptor import TransportDescriptor

__all__ = ["DESCRIPTOR", "describe", "observer_options", "router_environment"]


def observer_options(connect: Sequence[str] | None, mode: str | None) -> dict[str, Any]:
    """A session that reaches a running graph through ``connect`` (default: rmw_zenoh's router on this host)."""
    options: dict[str, Any] = {}
    if connect:
        options["connect"] = list(connect)
    if mode:
        options["mode"] = mode
    return options


def router_environment(endpoint: str) -> dict[str, str]:
    """rmw_zenoh's own ``ZENOH_CONFIG_OVERRIDE``: connect to the router at ``endpoint``, listen on loopback only."""
    return {"ZENOH_CONFIG_OVERRIDE": f'connect/endpoints=["{endpoint}"];listen/endpoints=["tcp/127.0.0.1:0"]'}


def describe(transport: Any) -> str:
    """Domain and endpoints of an open rmw_zenoh transport."""
    driver = getattr(transport, "driver", None)
    options = getattr(driver, "options", {}) or {}
    parts = [f"ROS domain {getattr(driver, 'domain_id', '?')}"]
    parts.append("connect " + ", ".join(options.get("connect") or ["tcp/localhost:7447 (rmw_zenoh's default)"]))
    return "; ".join(parts)


#: ROS 2 over Zenoh in rmw_zenoh's format (``Launcher(transport="rmw_zenoh")``).
DESCRIPTOR = TransportDescriptor(
    name="rmw_zenoh", factory="agents_zenoh.rmw.transport:RmwZenohTransport", title="ROS 2 on rmw_zenoh",
    extra="rmw-zenoh", requires=("zenoh", "rosbags", "xxhash", "std_msgs"), needs_router=True,
    router="agents_zenoh.router", router_environment=router_environment,
    rendezvous="tcp/localhost:7447", endpoints=True,
    carries=frozenset({"values", "requests", "goals", "discovery", "cross-process", "attach"}),
    observer_options=observer_options, describe=describe, pair="agents_zenoh.rmw.testing:rmw_zenoh_pair")
