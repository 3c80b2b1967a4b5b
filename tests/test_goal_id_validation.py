"""The core's goal-id check, shared by every transport: 32 lowercase ASCII hex digits, nothing else."""

from __future__ import annotations

import uuid

import pytest

from agents_core.transport.goal_serving import new_goal_id, valid_goal_id
from agents_core.transport.memory import MemoryTransport


@pytest.mark.parametrize("goal_id", ["٣" * 32, "é" * 32, "Ⅻ" * 32, "A" * 32, "0" * 31 + "\n", "0" * 64, "", None, 7,
                                     b"0" * 32])
def test_non_hex_ids_are_invalid(goal_id: object) -> None:
    assert not valid_goal_id(goal_id)


def test_fresh_and_ros_ids_are_valid() -> None:
    assert valid_goal_id(new_goal_id())
    assert valid_goal_id(bytes(range(16)).hex())  # a ROS 2 UUID as agents_ros2 renders it
    assert valid_goal_id(uuid.uuid4().hex)


def test_the_memory_transport_server_rejects_a_unicode_digit_id() -> None:
    with MemoryTransport() as t:
        server = t.create_action_server("arm", "VisionLanguageAction", lambda h: {})
        reason = server.on_goal("٣" * 32, {"task": "x"})
        assert reason is not None and "32 lowercase hex digits" in reason
        assert server.on_cancel("٣" * 32) is False
        assert server.statistics().accepted == 0
