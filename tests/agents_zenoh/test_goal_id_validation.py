"""Goal ids from the network are exactly 32 lowercase ASCII hex digits, as docs/zenoh-wire-format.md says.

``str.isalnum`` (the old check) also takes Unicode letters and digits, which then ended up in
Zenoh key expressions (``<base>/@action/status/<goal_id>``) and in logs.
"""

from __future__ import annotations

import uuid

import pytest

pytest.importorskip("zenoh")

from .goal_peers import served_action

BAD_IDS = [
    "٣" * 32,                      # Arabic-Indic digit three: str.isdigit() is True
    "é" * 32,                      # a Latin letter outside ASCII: str.isalnum() is True
    "\uff41" * 32,                 # fullwidth "a"
    "ABCDEF0123456789" * 2,        # upper case: not the documented form
    "0" * 31,
    "0" * 33,
    "0" * 31 + "g",
    "0" * 31 + "\n",
    "",
]


@pytest.mark.parametrize("goal_id", BAD_IDS, ids=[f"bad{i}" for i in range(len(BAD_IDS))])
def test_a_goal_with_a_non_hex_id_is_rejected_naming_the_form(goal_id: str) -> None:
    with served_action() as (server, _client, peer):
        ok, answer = peer.ask("goal", {"goal_id": goal_id, "goal": {"task": "x"}})
        assert ok and answer["accepted"] is False
        assert "invalid goal id" in answer["reason"] and "32 lowercase hex digits" in answer["reason"]
        assert peer.ask("cancel", {"goal_id": goal_id}) == (True, {"accepted": False})
        assert server.statistics().accepted == 0 and server.statistics().rejected == 1


def test_a_hex_goal_id_is_accepted() -> None:
    with served_action() as (server, _client, peer):
        ok, answer = peer.ask("goal", {"goal_id": uuid.uuid4().hex, "goal": {"task": "x"}})
        assert ok and answer == {"accepted": True, "reason": ""}
        assert server.statistics().accepted == 1
