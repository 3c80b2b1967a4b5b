"""The end of every recipe file the transport tests run in a process of its own.

``serve(launcher)`` starts the launcher, prints ``READY`` for the test, runs until SIGINT / SIGTERM
(bounded, so a forgotten recipe ends by itself) and prints ``stopped cleanly`` once it has stopped.
"""

from __future__ import annotations

import logging
import signal
import sys
import threading
from typing import Any

from agents_core import Launcher

#: A forgotten recipe process stops by itself after this many seconds.
MAX_RUN_SECONDS = 600.0


def transport_options(transport: str, listen: str) -> dict[str, Any]:
    """Zenoh: a loopback peer listening on ``listen`` (the test connects there); others: none."""
    return {"mode": "peer", "listen": [listen], "connect": []} if transport == "zenoh" else {}


def serve(launcher: Launcher, log_level: int = logging.INFO) -> None:
    """Run ``launcher`` until a signal (see the module docstring)."""
    logging.basicConfig(level=log_level, stream=sys.stderr, format="%(levelname)s %(name)s: %(message)s")
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    with launcher:
        print("READY", flush=True)
        stop.wait(MAX_RUN_SECONDS)
    print("stopped cleanly", file=sys.stderr, flush=True)
