"""The conformance pair of the rmw_zenoh transport: a router on a free loopback port and two peers of it."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from agents_core.testing.helpers import free_tcp_port
from agents_core.transport.contract import Transport

__all__ = ["rmw_zenoh_pair"]


@contextlib.contextmanager
def rmw_zenoh_pair() -> Iterator[tuple[Transport, Transport]]:
    """Yield ``(a, b)``: two rmw_zenoh transports (domain 0) meeting through a router on loopback."""
    from agents_zenoh.router import open_router  # noqa: PLC0415

    from .transport import RmwZenohTransport  # noqa: PLC0415

    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    router = open_router([endpoint])
    opened: list[Transport] = []
    try:
        for _ in range(2):
            opened.append(RmwZenohTransport(connect=[endpoint], listen=["tcp/127.0.0.1:0"]))
        yield opened[0], opened[1]
    finally:
        for transport in opened:
            transport.close()
        router.close()  # type: ignore[no-untyped-call]
