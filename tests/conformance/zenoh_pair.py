"""Two Zenoh transports in this process that reach each other over loopback.

Used by the conformance suite (see conftest.py). Each transport has a session of its own,
listening on an explicit ``tcp/127.0.0.1`` port; ``b`` connects to ``a``. Multicast scouting
is off, so nothing leaves the host and parallel runs never meet.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from agents_zenoh.transport import ZenohTransport

from ..conftest import free_tcp_port

# Zenoh's open() waits up to scouting/delay (500 ms by default) for its connections; on
# loopback they take a few ms, so a short delay saves half a second per test.
_FAST_OPEN = {"scouting/delay": 50}


@contextlib.contextmanager
def zenoh_pair() -> Iterator[tuple[ZenohTransport, ZenohTransport]]:
    """Yield ``(a, b)``: two peers on loopback, ``b`` connected to ``a``; both closed on exit."""
    port_a = free_tcp_port()
    a = ZenohTransport(mode="peer", listen=[f"tcp/127.0.0.1:{port_a}"], connect=[], multicast_scouting=False,
                       zenoh_options=_FAST_OPEN)
    try:
        b = ZenohTransport(mode="peer", listen=[f"tcp/127.0.0.1:{free_tcp_port()}"],
                           connect=[f"tcp/127.0.0.1:{port_a}"], multicast_scouting=False,
                           zenoh_options=_FAST_OPEN)
    except BaseException:
        a.close()
        raise
    try:
        yield a, b
    finally:
        b.close()
        a.close()
