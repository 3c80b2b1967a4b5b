"""Shared fixtures and helpers for the test suite."""

from __future__ import annotations

import time
from collections.abc import Callable

import pytest

from agents_core.transport import MemoryTransport


def wait_for(predicate: Callable[[], bool], timeout: float = 5.0, interval: float = 0.005) -> bool:
    """Poll ``predicate`` until true or ``timeout`` seconds pass (bounded); returns the last result."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return predicate()


@pytest.fixture
def memory() -> MemoryTransport:
    transport = MemoryTransport()
    yield transport
    transport.close()
