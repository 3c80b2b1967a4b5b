"""The Zenoh transport, described for the core (:class:`~agents_core.transport.descriptor.TransportDescriptor`).

Importing this module does not import ``zenoh``: the CLI and the launcher read it to learn how a
process reaches a Zenoh graph (endpoints, a client of a router) before anything is opened.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from agents_core.transport.descriptor import TransportDescriptor

__all__ = ["DESCRIPTOR", "describe", "listener_options", "observer_options"]

#: Where Zenoh processes on one host meet when no endpoint is given (:class:`~agents_zenoh.ZenohConfig`).
RENDEZVOUS = "tcp/127.0.0.1:7447"


def observer_options(connect: Sequence[str] | None, mode: str | None) -> dict[str, Any]:
    """A session that reaches a running graph: a client of ``connect`` (or ``mode``), else the loopback rendezvous."""
    options: dict[str, Any] = {"zenoh_options": {"scouting/delay": 100}}
    if connect:
        options.update(mode=mode or "client", connect=list(connect), listen=[])
    elif mode is not None:
        options.update(mode=mode)
    return options


def listener_options(endpoint: str) -> dict[str, Any]:
    """A peer the others reach at ``endpoint``, on this host only (multicast scouting off)."""
    return {"mode": "peer", "listen": [endpoint], "connect": [], "multicast_scouting": False}


def describe(transport: Any) -> str:
    """Mode, endpoints, scouting and namespace of an open Zenoh transport (read from its driver's config)."""
    config = getattr(getattr(transport, "driver", None), "config", None)
    if config is None:
        return ""
    mode = getattr(config, "mode", None) or "peer"
    listen = getattr(config, "listen", None)
    connect = getattr(config, "connect", None)
    parts = [str(mode)]
    if getattr(config, "config_file", None):
        parts.append(f"config file {config.config_file}")
    elif listen is None and connect is None:
        port = getattr(config, "port", 7447)
        parts.append(f"loopback rendezvous tcp/127.0.0.1:{port}")
    if listen:
        parts.append("listen " + ", ".join(listen))
    if connect:
        parts.append("connect " + ", ".join(connect))
    parts.append("multicast scouting " + ("on" if getattr(config, "multicast_scouting", False) else "off"))
    namespace = getattr(config, "namespace", "")
    if namespace:
        parts.append(f"namespace {namespace}")
    if getattr(transport.driver, "joined_rendezvous", False):
        parts.append("joined the peers already there: another recipe on this host shares its topics (give each "
                     "recipe its own AGENTS_ZENOH_PORT to keep them apart)")
    return "; ".join(parts)


#: The Zenoh transport (``Launcher(transport="zenoh")``).
DESCRIPTOR = TransportDescriptor(
    name="zenoh", factory="agents_zenoh.transport:ZenohTransport", title="Zenoh", extra="zenoh",
    requires=("zenoh",), rendezvous=RENDEZVOUS, endpoints=True,
    carries=frozenset({"values", "requests", "goals", "discovery", "cross-process", "attach"}),
    observer_options=observer_options, listener_options=listener_options, describe=describe)
