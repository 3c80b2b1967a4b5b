"""A peer that only reads ``@action/status/*`` cannot cancel another client's goal on Zenoh.

Goal ids are in the status keys every peer can subscribe to; a cancel must carry the goal's
``cancel_token``, which only the goal's sender and the server know (docs/zenoh-wire-format.md).
"""

from __future__ import annotations

import secrets
import time
import uuid

import pytest

pytest.importorskip("zenoh")

from agents_core.testing.helpers import wait_for
from agents_core.transport.goals import GoalStatus

from .goal_peers import ACTION, served_action


def test_a_peer_that_sees_the_status_cannot_cancel_the_goal() -> None:
    with served_action() as (server, client, peer):
        goal = client.send_goal(ACTION, "VisionLanguageAction", {"task": "hold"}, timeout=5.0)
        assert goal.accepted
        assert wait_for(lambda: goal.goal_id in peer.seen_ids, timeout=5.0)  # the peer learned the id
        stolen = peer.seen_ids[0]
        assert peer.ask("cancel", {"goal_id": stolen}) == (True, {"accepted": False, "reason":
                                                                   "the cancel token does not match the goal's"})
        assert peer.ask("cancel", {"goal_id": stolen, "cancel_token": secrets.token_hex(16)})[1]["accepted"] is False
        # Re-sending the running goal's id with a token of its own does not replace the goal's token.
        mine = secrets.token_hex(16)
        ok, answer = peer.ask("goal", {"goal_id": stolen, "goal": {"task": "x"}, "cancel_token": mine})
        assert ok and answer["accepted"] is False and "already in use" in answer["reason"]
        assert peer.ask("cancel", {"goal_id": stolen, "cancel_token": mine})[1]["accepted"] is False
        time.sleep(0.2)
        assert goal.status in (GoalStatus.ACCEPTED, GoalStatus.EXECUTING) and not goal.done
        # Its sender can.
        assert goal.cancel(5.0) is True
        status, result = goal.result(10.0)
        assert status == GoalStatus.CANCELED and result["success"] is False
        assert server.statistics().canceled == 1


def test_a_malformed_cancel_token_is_refused_with_the_reason() -> None:
    with served_action() as (server, _client, peer):
        for token in (7, "short", "x" * 129, "é" * 32):
            ok, answer = peer.ask("goal", {"goal_id": uuid.uuid4().hex, "goal": {"task": "x"}, "cancel_token": token})
            assert not ok and "cancel_token must be an ASCII str" in answer["error"]
        ok, answer = peer.ask("cancel", {"goal_id": uuid.uuid4().hex, "cancel_token": ["not", "a", "str"]})
        assert not ok and "cancel_token" in answer["error"]
        assert server.statistics().decode_errors == 5 and server.statistics().accepted == 0


def test_a_goal_sent_without_a_token_stays_cancellable_by_its_id() -> None:
    """Compatibility: clients written before cancel tokens existed still cancel their goals."""
    with served_action() as (server, _client, peer):
        goal_id = uuid.uuid4().hex
        assert peer.ask("goal", {"goal_id": goal_id, "goal": {"task": "old"}}) == (True, {"accepted": True,
                                                                                        "reason": ""})
        assert peer.ask("cancel", {"goal_id": goal_id}) == (True, {"accepted": True})
        ok, doc = peer.ask("result", {"goal_id": goal_id, "wait_s": 5.0}, timeout=10.0)
        assert ok and doc["status"] == int(GoalStatus.CANCELED)
        assert server.statistics().canceled == 1
