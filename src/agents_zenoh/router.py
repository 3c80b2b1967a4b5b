"""A Zenoh router in Python, for setups across machines (``zenohd`` is not on PyPI).

Recipes on several hosts run as Zenoh *clients* connected to one router; everything they
exchange goes through it. :func:`open_router` opens a session in ``router`` mode on explicit
endpoints with multicast scouting off; :func:`serve_router` keeps it open until SIGINT / SIGTERM
(what ``agentsctl router --listen tcp/0.0.0.0:7447`` runs).
"""

from __future__ import annotations

import logging
import signal
import threading
from collections.abc import Callable
from typing import Any

import zenoh

from agents_core.errors import TransportError

from .config import ZenohConfig
from .session import zenoh_config

__all__ = ["open_router", "serve_router"]

logger = logging.getLogger(__name__)


def open_router(listen: list[str], connect: list[str] | None = None) -> zenoh.Session:
    """A Zenoh session in router mode listening on ``listen`` (and linked to other routers in ``connect``)."""
    if not listen:
        raise TransportError("a router needs at least one --listen endpoint, e.g. tcp/0.0.0.0:7447")
    config = ZenohConfig(mode="router", listen=list(listen), connect=list(connect or []))
    try:
        return zenoh.open(zenoh_config(config))
    except zenoh.ZError as exc:
        raise TransportError(f"cannot open a Zenoh router on {listen}: {exc}") from exc


def serve_router(listen: list[str], connect: list[str] | None = None,
                 on_ready: Callable[[zenoh.Session], None] | None = None) -> None:
    """Run a router until SIGINT or SIGTERM; ``on_ready(session)`` is called once it listens."""
    stop = threading.Event()

    def request_stop(_signum: int, _frame: Any) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, request_stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    session = open_router(listen, connect)
    try:
        if on_ready is not None:
            on_ready(session)
        while not stop.wait(0.5):
            pass
    finally:
        session.close()  # type: ignore[no-untyped-call]  # zenoh's stub leaves it unannotated
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        logger.info("Zenoh router stopped")
