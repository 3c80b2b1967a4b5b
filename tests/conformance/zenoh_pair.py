"""Two Zenoh transports on loopback: kept for the tests that import it; the pair now ships in the plugin."""

from __future__ import annotations

from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.pairs import zenoh_pair

__all__ = ["free_tcp_port", "zenoh_pair"]
