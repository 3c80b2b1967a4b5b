"""The descriptors of the test's own transports (what a third-party package's entry point loads)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from agents_core.transport.descriptor import TransportDescriptor

__all__ = ["MEMLOOP", "ZENLOOP", "install_entry_points"]


def _reach(connect: Sequence[str] | None, mode: str | None) -> dict[str, Any]:
    if connect:
        return {"mode": mode or "client", "connect": list(connect), "listen": []}
    return {}


def _listen(endpoint: str) -> dict[str, Any]:
    return {"mode": "peer", "listen": [endpoint], "connect": [], "multicast_scouting": False}


def _describe(transport: Any) -> str:
    config = getattr(getattr(transport, "driver", None), "config", None)
    return f"the test's own; listen {', '.join(getattr(config, 'listen', None) or []) or '-'}"


ZENLOOP = TransportDescriptor(
    name="zenloop", factory="tests.fourth_transport.transport:ZenloopTransport", title="Zenloop",
    requires=("zenoh",), endpoints=True,
    carries=frozenset({"values", "requests", "goals", "discovery", "cross-process", "attach"}),
    observer_options=_reach, listener_options=_listen, describe=_describe)

MEMLOOP = TransportDescriptor(
    name="memloop", factory="tests.fourth_transport.transport:MemloopTransport", title="Memloop",
    in_process=True, carries=frozenset({"values", "requests"}))


def install_entry_points(site: Path) -> Path:
    """Write a distribution's metadata registering both transports under ``site``; put ``site`` on the path."""
    info = site / "fourth_transport-0.1.dist-info"
    info.mkdir(parents=True, exist_ok=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: fourth-transport\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[agents_core.transports]\n"
        "zenloop = tests.fourth_transport.descriptor:ZENLOOP\n"
        "memloop = tests.fourth_transport.descriptor:MEMLOOP\n")
    return site
