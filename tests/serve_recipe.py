"""A test recipe run in a process of its own: the "recipe running elsewhere" of the UI and MCP tests.

``python -m tests.ui.ui_parts --listen tcp/127.0.0.1:PORT`` (or ``tests.mcp.mcp_parts``; with
``--transport ros2``: on ROS 2) calls :func:`serve` with its components; it prints READY once they
are active and stops on SIGTERM / SIGINT (or after 300 s: the test stops it long before).
"""

from __future__ import annotations

import argparse
import signal
import threading
from collections.abc import Callable, Sequence
from typing import Any

from agents_core import Launcher

__all__ = ["serve"]


def serve(make_components: Callable[[], list[Any]], argv: Sequence[str] | None = None) -> int:
    """Run ``make_components()`` on the transport the command line names until stopped."""
    parser = argparse.ArgumentParser()
    parser.add_argument("--transport", default="zenoh", choices=["zenoh", "ros2"])
    parser.add_argument("--listen", help="the Zenoh endpoint (tcp/127.0.0.1:PORT)")
    args = parser.parse_args(argv)
    options = ({"mode": "peer", "listen": [args.listen], "connect": [], "multicast_scouting": False}
               if args.transport == "zenoh" else {})
    launcher = Launcher(args.transport, transport_options=options)
    launcher.add_pkg(components=make_components())
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    with launcher:
        print("READY", flush=True)
        stop.wait(300)  # bounded: the test stops it long before
    return 0
