"""A Zenoh router in Python, for setups across machines (``zenohd`` is not on PyPI).

Recipes on several hosts run as Zenoh *clients* connected to one router; everything they
exchange goes through it. :func:`open_router` opens a session in ``router`` mode on explicit
endpoints with multicast scouting off; :func:`serve_router` keeps it open until SIGINT / SIGTERM
(what ``agentsctl router --listen tcp/0.0.0.0:7447`` runs). ``python -m agents_zenoh.router ENDPOINT...`` runs
one without the CLI and prints ``READY`` once it listens (the test harness's router, see
:mod:`agents_core.testing.recipes`).

Routers joined with ``connect`` (``agentsctl router --listen ... --connect tcp/other:7447``, one
per other router) form a *mesh*: a client of any of them reaches the clients of every other one,
and a router that goes away is retried until it is back. :func:`router_peers` lists what a router
is linked to (other routers, peers, clients: their Zenoh ids and link endpoints); ``serve_router``
reports it each time it changes.
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

__all__ = ["open_router", "router_peers", "serve_router"]

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


def router_peers(session: zenoh.Session) -> list[dict[str, Any]]:
    """What the router ``session`` is linked to: ``{"zid", "kind" ("router" / "peer" / "client"), "links"}`` each,
    sorted by kind then id; ``links`` holds each link's ``"src -> dst"`` endpoints."""
    links: dict[str, list[str]] = {}
    for link in session.info.links():
        links.setdefault(str(link.zid), []).append(f"{link.src} -> {link.dst}")
    found = []
    for transport in session.info.transports():
        zid = str(transport.zid)
        found.append({"zid": zid, "kind": str(transport.whatami).rsplit(".", 1)[-1].lower(),
                      "links": sorted(links.get(zid, []))})
    return sorted(found, key=lambda p: (p["kind"], p["zid"]))


def serve_router(listen: list[str], connect: list[str] | None = None,
                 on_ready: Callable[[zenoh.Session], None] | None = None,
                 on_peers: Callable[[list[dict[str, Any]]], None] | None = None) -> None:
    """Run a router until SIGINT or SIGTERM; ``on_ready(session)`` is called once it listens, ``on_peers(peers)``
    (:func:`router_peers`) whenever the set of routers, peers and clients linked to it changes (polled at 2 Hz)."""
    stop = threading.Event()

    def request_stop(_signum: int, _frame: Any) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, request_stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    session = open_router(listen, connect)
    try:
        if on_ready is not None:
            on_ready(session)
        shown: list[tuple[str, str]] | None = None
        while True:
            if on_peers is not None:
                peers = router_peers(session)
                now = [(p["kind"], p["zid"]) for p in peers]
                if now != shown:
                    shown = now
                    on_peers(peers)
            if stop.wait(0.5):
                break
    finally:
        session.close()  # type: ignore[no-untyped-call]  # zenoh's stub leaves it unannotated
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        logger.info("Zenoh router stopped")


if __name__ == "__main__":
    import sys

    serve_router(sys.argv[1:], on_ready=lambda _session: print("READY", flush=True))
