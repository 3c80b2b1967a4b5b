"""Fixtures for the goal wire tests: a framework action server on Zenoh and a raw zenoh + msgpack peer.

The raw peer is what any program on the network could run (``raw_goal_client``'s helpers): it
sees what a peer sees and sends what a peer can send.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from typing import Any

import msgpack
import zenoh

from agents_core.testing.helpers import free_tcp_port, wait_for
from agents_core.transport.goal_serving import CoreActionServer
from agents_core.transport.goals import GoalHandle
from agents_zenoh.transport import ZenohTransport

from .raw_goal_client import open_peer, query

__all__ = ["ACTION", "RawPeer", "run_until_cancelled", "served_action"]

ACTION = "arm_goal"


def run_until_cancelled(handle: GoalHandle) -> dict[str, Any]:
    """Execute callback: feedback every 20 ms until cancelled (or 30 s)."""
    step = 0
    deadline = time.monotonic() + 30.0
    while not handle.wait_for_cancel(0.02) and time.monotonic() < deadline:
        step += 1
        handle.publish_feedback({"step": step})
    return {"success": not handle.cancel_requested, "steps": step}


class RawPeer:
    """A plain zenoh peer connected to the server: queries the goal keys, records status samples."""

    def __init__(self, session: zenoh.Session) -> None:
        self.session = session
        self.seen_ids: list[str] = []
        self._sub = session.declare_subscriber(f"{ACTION}/@action/status/*", self._on_status)

    def _on_status(self, sample: zenoh.Sample) -> None:
        goal_id = str(sample.key_expr).rsplit("/", 1)[-1]
        if goal_id not in self.seen_ids:
            self.seen_ids.append(goal_id)

    def ask(self, part: str, request: dict[str, Any], timeout: float = 5.0) -> tuple[bool, Any]:
        """(ok, decoded reply) of a query to ``<action>/@action/<part>``; (False, None) with no reply."""
        return query(self.session, f"{ACTION}/@action/{part}", msgpack.packb(request), timeout)


@contextlib.contextmanager
def served_action() -> Iterator[tuple[CoreActionServer, ZenohTransport, RawPeer]]:
    """(action server, framework client transport, raw peer); the server runs :func:`run_until_cancelled`."""
    port = free_tcp_port()
    server = ZenohTransport(mode="peer", listen=[f"tcp/127.0.0.1:{port}"], connect=[], multicast_scouting=False)
    client = session = None
    try:
        action_server = server.create_action_server(ACTION, "VisionLanguageAction", run_until_cancelled)
        client = ZenohTransport(mode="peer", listen=[], connect=[f"tcp/127.0.0.1:{port}"], multicast_scouting=False)
        session = open_peer(f"tcp/127.0.0.1:{port}")
        peer = RawPeer(session)
        # The connections are made asynchronously: wait until the raw peer reaches the server.
        assert wait_for(lambda: peer.ask("result", {"goal_id": "0" * 32}, 1.0)[1] is not None, timeout=10.0)
        yield action_server, client, peer
    finally:
        if session is not None:
            session.close()
        if client is not None:
            client.close()
        server.close()
