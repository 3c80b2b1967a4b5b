"""Events as data for a component process (agents_core.declarations.event_transfer): what crosses, what is refused."""

from __future__ import annotations

import pytest

from agents_core.declarations.event_transfer import decode_event, encode_event
from agents_core.errors import ConfigError
from agents_core.events import Event
from agents_core.launch.spec import decode_value, encode_value
from agents_core.topics import Topic

DONE = Topic(name="arm_done", msg_type="Bool")
STATE = Topic(name="joint_states", msg_type="JointState")


def test_conditions_cross_processes_as_data() -> None:
    combined = Event("both", (DONE.msg.data == True) & ~(STATE.msg.name.contains("x")))  # noqa: E712
    copy = decode_event(encode_event(combined))
    assert copy.name == "both" and set(copy.topics) == {"arm_done", "joint_states"}
    assert copy.event_condition is not None and "arm_done" in repr(copy)


def test_a_manual_event_cannot_reach_a_process_and_says_so() -> None:
    with pytest.raises(ConfigError, match="fires only when code calls trigger"):
        encode_event(Event("by_hand"))


def test_the_rebuilt_condition_evaluates_as_the_original() -> None:
    level = Topic(name="level", msg_type="Float64")
    original = Event("far", (level.msg.data > 0.5) & ~(level.msg.data >= 0.9), on_change=True)
    copy = decode_value(encode_value(original))
    assert isinstance(copy, Event) and copy.on_change and copy is not original
    assert [copy.process("level", v) for v in (0.2, 0.7, 0.8, 0.95, 0.6)] == [False, True, False, False, True]


def test_a_condition_from_a_function_is_refused_by_name() -> None:
    from agents_core.conditions import Condition  # noqa: PLC0415

    event = Event("custom", Condition(lambda v: True, "my check", {"arm_done": DONE}))
    with pytest.raises(ConfigError, match="made from a function"):
        encode_value(event)
