"""Shared fixtures and helpers for the test suite."""

from __future__ import annotations

import pytest

from agents_core.testing.helpers import free_tcp_port, wait_for
from agents_core.transport import MemoryTransport

__all__ = ["free_tcp_port", "wait_for"]


@pytest.fixture
def memory() -> MemoryTransport:
    transport = MemoryTransport()
    yield transport
    transport.close()
