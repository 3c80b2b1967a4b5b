"""A result query's ``wait_s`` is clamped to 0..5 s, and NaN is refused (it used to hold the query forever).

A NaN deadline compares false with every time, so the server's sweeper never answered such a query
"pending": it stayed held (a slot of the 16 per goal) until the goal ended.
"""

from __future__ import annotations

import time
import uuid

import pytest

pytest.importorskip("zenoh")

from .goal_peers import RawPeer, served_action


def _running_goal(peer: RawPeer) -> str:
    goal_id = uuid.uuid4().hex
    ok, answer = peer.ask("goal", {"goal_id": goal_id, "goal": {"task": "hold"}})
    assert ok and answer["accepted"] is True
    return goal_id


def test_a_nan_wait_is_refused_at_once() -> None:
    with served_action() as (server, _client, peer):
        goal_id = _running_goal(peer)
        started = time.monotonic()
        ok, answer = peer.ask("result", {"goal_id": goal_id, "wait_s": float("nan")}, timeout=8.0)
        took = time.monotonic() - started
        assert not ok and answer is not None and "not NaN" in answer["error"], answer
        assert took < 2.0
        assert server.statistics().decode_errors == 1


def test_a_negative_wait_is_answered_pending_at_once() -> None:
    with served_action() as (_server, _client, peer):
        goal_id = _running_goal(peer)
        for wait in (-1.0, float("-inf"), -(10**6)):
            started = time.monotonic()
            assert peer.ask("result", {"goal_id": goal_id, "wait_s": wait}, timeout=8.0) == (True, {"pending": True})
            assert time.monotonic() - started < 2.0


@pytest.mark.slow
def test_an_infinite_or_huge_wait_is_capped_at_five_seconds() -> None:
    with served_action() as (_server, _client, peer):
        goal_id = _running_goal(peer)
        for wait in (float("inf"), 1e308):
            started = time.monotonic()
            assert peer.ask("result", {"goal_id": goal_id, "wait_s": wait}, timeout=9.0) == (True, {"pending": True})
            assert 4.5 < time.monotonic() - started < 7.0
