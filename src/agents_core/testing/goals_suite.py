"""The conformance tests of long-running goals, collected with the rest of the suite.

:mod:`agents_core.testing.suite` imports these tests, so they run on every transport whose
``capabilities.actions`` is True and are skipped (with the reason) on the others. ``a`` serves
the action, ``b`` sends goals.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest

from agents_core.errors import (
    ComponentError,
    ServiceUnavailableError,
    TransportError,
    TypeValidationError,
    UnknownTypeError,
)
from agents_core.transport import Transport
from agents_core.transport.goals import GoalHandle, GoalStatus

from .helpers import wait_for

__all__ = [
    "test_goal_a_raising_execute_aborts_with_its_message",
    "test_goal_bad_goal_fields_are_refused_before_sending",
    "test_goal_cancel_mid_goal_and_cancel_of_a_finished_goal",
    "test_goal_inline_feedback_refuses_waiting_calls_and_cancels_without_waiting",
    "test_goal_rejected_by_accept_and_nobody_serving",
    "test_goal_round_trip_with_feedback",
    "test_goal_server_closed_mid_goal_aborts_the_client",
    "test_goal_several_goals_run_at_once",
    "test_goal_unsupported_transport_says_so",
]

VLA = "VisionLanguageAction"
_counter = iter(range(1_000_000))


def _name(what: str) -> str:
    return f"goal_{what}_{next(_counter)}_{int(time.time() * 1000) % 100000}"


def _needs_actions(a: Transport) -> None:
    if not a.capabilities.actions:
        pytest.skip(f"the {a.name} transport has no long-running goals (capabilities.actions is False)")


def _send(b: Transport, name: str, goal: dict[str, Any], **kwargs: Any) -> Any:
    """Send a goal, retrying while discovery has not yet found the server (networked transports)."""
    deadline = time.monotonic() + 10.0
    while True:
        try:
            return b.send_goal(name, VLA, goal, timeout=5.0, **kwargs)
        except ServiceUnavailableError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)


def test_goal_round_trip_with_feedback(transport_pair: tuple[Transport, Transport]) -> None:
    a, b = transport_pair
    _needs_actions(a)
    name = _name("round_trip")
    seen_threads: list[str] = []

    def execute(handle: GoalHandle) -> dict[str, Any]:
        seen_threads.append(threading.current_thread().name)
        for step in range(5):
            handle.publish_feedback({"step": step, "action": [float(step), -1.5], "status": "moving"})
            time.sleep(0.01)
        return {"success": True, "message": f"done {handle.goal['task']}", "steps": handle.goal["max_steps"]}

    server = a.create_action_server(name, VLA, execute)
    feedback: list[dict[str, Any]] = []
    goal = _send(b, name, {"task": "pick the cube", "max_steps": 5}, feedback=feedback.append)
    assert goal.accepted and len(goal.goal_id) == 32
    status, result = goal.result(10.0)
    assert status == GoalStatus.SUCCEEDED and goal.status == GoalStatus.SUCCEEDED
    assert result == {"success": True, "message": "done pick the cube", "steps": 5}
    assert wait_for(lambda: len(feedback) == 5, timeout=5.0), feedback
    assert [f["step"] for f in feedback] == [0, 1, 2, 3, 4]
    assert feedback[3] == {"step": 3, "action": [3.0, -1.5], "status": "moving"}
    assert seen_threads and seen_threads[0].startswith(f"{name}:goal:")
    assert goal.cancel(1.0) is False  # cancel of a finished goal
    server.close()


def test_goal_cancel_mid_goal_and_cancel_of_a_finished_goal(transport_pair: tuple[Transport, Transport]) -> None:
    a, b = transport_pair
    _needs_actions(a)
    name = _name("cancel")
    started = threading.Event()

    def execute(handle: GoalHandle) -> dict[str, Any]:
        started.set()
        steps = 0
        while not handle.wait_for_cancel(0.02):
            steps += 1
            handle.publish_feedback({"step": steps, "action": [], "status": "running"})
        return {"success": False, "message": "stopped", "steps": steps}

    server = a.create_action_server(name, VLA, execute)
    feedback: list[dict[str, Any]] = []
    goal = _send(b, name, {"task": "wave"}, feedback=feedback.append)
    assert goal.accepted
    assert started.wait(5.0)
    assert wait_for(lambda: len(feedback) >= 2, timeout=5.0)
    assert goal.cancel(5.0) is True
    status, result = goal.result(10.0)
    assert status == GoalStatus.CANCELED
    assert result["message"] == "stopped" and result["steps"] >= 2
    assert goal.cancel(1.0) is False
    server.close()


def test_goal_inline_feedback_refuses_waiting_calls_and_cancels_without_waiting(
        transport_pair: tuple[Transport, Transport]) -> None:
    # A feedback_inline=True callback runs on the transport's own thread (Zenoh's: the one that would
    # bring in the answer a blocking call waits for). Calls that wait say so at once; cancel_async()
    # cancels the goal "stop when close enough"-style without waiting there.
    a, b = transport_pair
    _needs_actions(a)
    name = _name("inline")

    def execute(handle: GoalHandle) -> dict[str, Any]:
        steps = 0
        while not handle.wait_for_cancel(0.02) and steps < 1500:
            steps += 1
            handle.publish_feedback({"step": steps, "action": [], "status": "running"})
        return {"success": False, "message": "stopped", "steps": steps}

    server = a.create_action_server(name, VLA, execute)
    box: dict[str, Any] = {}
    seen: dict[str, Any] = {}

    def on_feedback(_fb: dict[str, Any]) -> None:
        goal = box.get("goal")
        if goal is None or "outcomes" in seen:
            return
        began = time.monotonic()
        outcomes: list[object] = []
        for call in (lambda: goal.cancel(3.0), lambda: goal.result(3.0),
                     lambda: b.send_goal(name, VLA, {"task": "again"}, timeout=3.0),
                     lambda: b.request(f"{name}_service", {}, timeout=3.0)):
            try:
                outcomes.append(call())
            except Exception as exc:
                outcomes.append(exc)
        seen["future"] = goal.cancel_async(5.0)
        seen["took"] = time.monotonic() - began
        seen["outcomes"] = outcomes

    goal = _send(b, name, {"task": "wave"}, feedback=on_feedback, feedback_inline=True)
    box["goal"] = goal
    assert goal.accepted
    assert wait_for(lambda: "outcomes" in seen, timeout=20.0)
    outcomes = seen["outcomes"]
    assert all(isinstance(o, ComponentError) and "feedback_inline" in str(o) for o in outcomes), outcomes
    assert seen["took"] < 1.0, seen["took"]
    assert seen["future"].result(10.0) is True
    status, result = goal.result(10.0)
    assert status == GoalStatus.CANCELED and result["message"] == "stopped"
    assert goal.cancel_async(1.0).result(5.0) is False  # a finished goal
    server.close()


def test_goal_rejected_by_accept_and_nobody_serving(transport_pair: tuple[Transport, Transport]) -> None:
    a, b = transport_pair
    _needs_actions(a)
    name = _name("reject")
    server = a.create_action_server(name, VLA, lambda h: {"success": True},
                                    accept=lambda goal: goal["task"] != "forbidden")
    goal = _send(b, name, {"task": "forbidden"})
    assert not goal.accepted
    status, result = goal.result(1.0)
    assert status == GoalStatus.REJECTED and "did not accept" in result["message"]
    ok = _send(b, name, {"task": "fine"})
    assert ok.accepted and ok.result(10.0)[0] == GoalStatus.SUCCEEDED
    server.close()
    started = time.monotonic()
    nobody = _name("nobody")
    with pytest.raises(ServiceUnavailableError, match=nobody):
        b.send_goal(nobody, VLA, {"task": "x"}, timeout=1.0)
    assert time.monotonic() - started < 5.0


def test_goal_bad_goal_fields_are_refused_before_sending(transport_pair: tuple[Transport, Transport]) -> None:
    a, b = transport_pair
    _needs_actions(a)
    with pytest.raises(TypeValidationError, match="max_steps"):
        b.send_goal(_name("bad"), VLA, {"task": "x", "max_steps": "ten"})
    with pytest.raises(TypeValidationError, match="unknown field"):
        b.send_goal(_name("bad"), VLA, {"task": "x", "speed": 2})
    with pytest.raises(TypeValidationError, match="max_steps"):
        b.send_goal(_name("bad"), VLA, {"task": "x", "max_steps": -1})
    with pytest.raises(UnknownTypeError, match="VisionLanguageAction"):
        a.create_action_server(_name("bad"), "VisionLanguageActon", lambda h: {})


def test_goal_a_raising_execute_aborts_with_its_message(transport_pair: tuple[Transport, Transport]) -> None:
    a, b = transport_pair
    _needs_actions(a)
    name = _name("raises")

    def execute(handle: GoalHandle) -> dict[str, Any]:
        raise RuntimeError("gripper jammed")

    server = a.create_action_server(name, VLA, execute)
    goal = _send(b, name, {"task": "grip"})
    status, result = goal.result(10.0)
    assert status == GoalStatus.ABORTED and "gripper jammed" in result["message"]
    bad_result = a.create_action_server(_name("bad_result"), VLA, lambda h: {"success": "yes"})
    goal = _send(b, bad_result.name, {"task": "grip"})
    status, result = goal.result(10.0)
    assert status == GoalStatus.ABORTED and "invalid result" in result["message"]
    server.close()
    bad_result.close()


def test_goal_server_closed_mid_goal_aborts_the_client(transport_pair: tuple[Transport, Transport]) -> None:
    a, b = transport_pair
    _needs_actions(a)
    name = _name("closed")
    started = threading.Event()

    def execute(handle: GoalHandle) -> dict[str, Any]:
        started.set()
        handle.wait_for_cancel(30.0)
        return {"success": False}

    server = a.create_action_server(name, VLA, execute)
    goal = _send(b, name, {"task": "long"})
    assert started.wait(5.0)
    began = time.monotonic()
    server.close()
    status, result = goal.result(10.0)
    assert status == GoalStatus.ABORTED and "closed" in result["message"], (status, result)
    assert time.monotonic() - began < 10.0


def test_goal_several_goals_run_at_once(transport_pair: tuple[Transport, Transport]) -> None:
    a, b = transport_pair
    _needs_actions(a)
    name = _name("parallel")
    barrier = threading.Barrier(3, timeout=5.0)

    def execute(handle: GoalHandle) -> dict[str, Any]:
        barrier.wait()  # only passes if all three goals run at the same time
        return {"success": True, "message": handle.goal["task"]}

    server = a.create_action_server(name, VLA, execute)
    goals = [_send(b, name, {"task": f"t{i}"}) for i in range(3)]
    results = [g.result(10.0) for g in goals]
    assert [r[1]["message"] for r in results] == ["t0", "t1", "t2"]
    assert all(r[0] == GoalStatus.SUCCEEDED for r in results)
    assert len({g.goal_id for g in goals}) == 3
    server.close()


def test_goal_unsupported_transport_says_so() -> None:
    """A driver without the goal primitives keeps actions off, and the transport says so clearly."""
    from agents_core.transport.core import DriverTransport  # noqa: PLC0415
    from agents_core.transport.driver import DriverBase  # noqa: PLC0415
    from agents_core.transport.memory import MemoryDriver  # noqa: PLC0415

    class NoGoals(MemoryDriver):
        # Back to the base's defaults: no long-running goals (the narrower memory types do not apply).
        serve_goals = DriverBase.serve_goals  # type: ignore[assignment]
        send_goal = DriverBase.send_goal  # type: ignore[assignment]

    assert not NoGoals.capabilities.actions
    transport = DriverTransport(NoGoals())
    try:
        with pytest.raises(TransportError, match="no long-running goals"):
            transport.send_goal("x", VLA, {"task": "x"})
        with pytest.raises(TransportError, match="no long-running goals"):
            transport.create_action_server("x", VLA, lambda h: {})
    finally:
        transport.close()
