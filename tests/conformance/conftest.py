"""The transport fixture of the conformance suite: one parameter per transport.

Each parameter yields a pair of transports ``(a, b)`` that reach each other: the same memory
transport twice, or two independent middleware sessions on loopback. A transport whose extra is
not installed is skipped with the reason shown.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator

import pytest

from agents_core.transport import MemoryTransport, Transport

# name -> "module:function" returning a context manager that yields (a, b)
PAIR_FACTORIES = {
    "memory": None,
    "zenoh": "tests.conformance.zenoh_pair:zenoh_pair",
    "ros2": "tests.conformance.ros2_pair:ros2_pair",
}


@pytest.fixture(params=sorted(PAIR_FACTORIES), ids=sorted(PAIR_FACTORIES))
def transport_pair(request: pytest.FixtureRequest) -> Iterator[tuple[Transport, Transport]]:
    name = request.param
    if name == "memory":
        transport = MemoryTransport()
        yield transport, transport
        transport.close()
        return
    module_name, _, func = PAIR_FACTORIES[name].partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        pytest.skip(f"{name} transport not available here: {exc}")
    with getattr(module, func)() as pair:
        yield pair
