"""Long-running goals in the core, on the memory transport: validation, bookkeeping and bad input."""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np
import pytest

from agents_core.errors import (
    ComponentError,
    ConfigError,
    RequestTimeoutError,
    TransportClosedError,
    TypeValidationError,
    UnknownTypeError,
)
from agents_core.transport import MemoryTransport, goal_serving
from agents_core.transport.goals import (
    ACTION_TYPES,
    ActionType,
    FieldSpec,
    GoalHandle,
    GoalStatus,
    action_type,
    register_action_type,
)
from tests.conftest import wait_for

VLA = "VisionLanguageAction"


def test_vision_language_action_fields_match_the_interface() -> None:
    vla = action_type(VLA)
    assert vla.ros_type == "agents_interfaces/action/VisionLanguageAction"
    assert vla.defaults("goal") == {"task": "", "max_steps": 0}
    assert vla.defaults("result") == {"success": False, "message": "", "steps": 0}
    assert vla.defaults("feedback") == {"step": 0, "action": [], "status": ""}


def test_values_are_checked_and_widened() -> None:
    vla = action_type(VLA)
    fb = vla.validate("feedback", {"step": np.int64(3), "action": np.array([1, 2.5], dtype=np.float32)})
    assert fb == {"step": 3, "action": [1.0, 2.5], "status": ""}
    assert type(fb["step"]) is int and all(type(v) is float for v in fb["action"])
    bad: list[tuple[dict[str, Any], str]] = [
        ({"step": True}, "must be an int"),
        ({"step": 1.5}, "must be an int"),
        ({"step": -1}, r"\[0, 4294967295\]"),
        ({"step": 2**32}, r"\[0, 4294967295\]"),
        ({"action": [1.0, float("nan")]}, r"action'\[1\] must be a finite float"),
        ({"action": "1,2"}, "must be a list"),
        ({"action": np.zeros((2, 2))}, "one-dimensional"),
        ({"status": 3}, "must be a str"),
        ({"speed": 1}, "unknown field"),
    ]
    for value, message in bad:
        with pytest.raises(TypeValidationError, match=message):
            vla.validate("feedback", value)
    with pytest.raises(TypeValidationError, match="must be a dict"):
        vla.validate("goal", ["task"])


def test_unknown_action_type_and_custom_types() -> None:
    with pytest.raises(UnknownTypeError, match="did you mean 'VisionLanguageAction'"):
        action_type("VisionLanguageActon")
    with pytest.raises(ConfigError, match="unknown field kind"):
        FieldSpec("complex")
    fib = ActionType(name="TestFibonacci", goal={"order": "int"}, result={"sequence": "list[int]"},
                     feedback={"partial": "list[int]"})
    register_action_type(fib)
    try:
        with MemoryTransport() as t:
            def execute(h: GoalHandle) -> dict[str, Any]:
                seq = [0, 1]
                while len(seq) < h.goal["order"]:
                    seq.append(seq[-1] + seq[-2])
                    h.publish_feedback({"partial": seq})
                return {"sequence": seq}

            t.create_action_server("fib", "TestFibonacci", execute)
            status, result = t.send_goal("fib", "TestFibonacci", {"order": 6}).result(5.0)
            assert status == GoalStatus.SUCCEEDED and result == {"sequence": [0, 1, 1, 2, 3, 5]}
            t.close()
    finally:
        ACTION_TYPES.unregister("TestFibonacci")


def test_handle_outcomes_abort_reason_preemption_and_late_feedback() -> None:
    handles: list[GoalHandle] = []

    def execute(h: GoalHandle) -> dict[str, Any]:
        handles.append(h)
        if h.goal["task"] == "abort":
            h.abort("camera lost")
            return {}
        if h.goal["task"] == "preempt":
            h.request_cancel()  # server-side preemption
            assert h.cancel_requested
            return {"steps": 1}
        return {"success": True}

    with MemoryTransport() as t:
        t.create_action_server("arm", VLA, execute)
        assert t.send_goal("arm", VLA, {"task": "abort"}).result(5.0) == (
            GoalStatus.ABORTED, {"success": False, "message": "camera lost", "steps": 0})
        assert t.send_goal("arm", VLA, {"task": "preempt"}).result(5.0)[0] == GoalStatus.CANCELED
        assert t.send_goal("arm", VLA, {"task": "ok"}).result(5.0)[0] == GoalStatus.SUCCEEDED
        with pytest.raises(ComponentError, match="has ended"):
            handles[-1].publish_feedback({"step": 1})
        with pytest.raises(ComponentError, match="already ended"):
            handles[-1].succeed()
        t.close()


def test_result_timeout_and_closed_transport() -> None:
    release = threading.Event()
    t = MemoryTransport()
    server = t.create_action_server("slow", VLA, lambda h: (release.wait(5.0), {"success": True})[1])
    goal = t.send_goal("slow", VLA, {"task": "x"})
    with pytest.raises(RequestTimeoutError, match=r"no result within 0\.05 s"):
        goal.result(0.05)
    release.set()
    assert goal.result(5.0)[0] == GoalStatus.SUCCEEDED
    with pytest.raises(ConfigError, match="timeout"):
        t.send_goal("slow", VLA, {"task": "x"}, timeout=float("inf"))
    assert server.statistics().succeeded == 1
    t.close()
    with pytest.raises(TransportClosedError):
        t.send_goal("slow", VLA, {"task": "x"})
    with pytest.raises(TransportClosedError):
        t.create_action_server("other", VLA, lambda h: {})


def test_server_side_bounds_and_network_input() -> None:
    """What a peer can send is bounded: bad ids, duplicate ids, too many goals, undecodable requests."""
    release = threading.Event()
    first = "abc1" * 8  # goal ids are 32 lowercase hex digits
    with MemoryTransport() as t:
        server = t.create_action_server("arm", VLA, lambda h: (release.wait(5.0), {})[1])
        assert "invalid goal id" in (server.on_goal("not-hex!", {"task": "x"}) or "")
        assert "invalid goal id" in (server.on_goal("a" * 65, {"task": "x"}) or "")
        assert "unknown field" in (server.on_goal(first, {"task": "x", "evil": 1}) or "")
        assert server.on_goal(first, {"task": "x"}) is None
        server.on_accepted(first)
        assert "already in use" in (server.on_goal(first, {"task": "x"}) or "")
        for i in range(goal_serving.MAX_RUNNING_GOALS - 1):
            assert server.on_goal(f"{i:032x}", {"task": "x"}) is None
        assert "already runs" in (server.on_goal("f" * 32, {"task": "x"}) or "")
        assert server.wait_result("nosuchgoal", 0.0) == (GoalStatus.UNKNOWN, {})
        assert server.wait_result(first, 0.01) is None
        assert server.on_cancel("nosuchgoal") is False
        server.reject("garbage")
        stats = server.statistics()
        assert stats.decode_errors == 1 and stats.rejected == 5 and stats.accepted == goal_serving.MAX_RUNNING_GOALS
        release.set()
        assert server.wait_result(first, 5.0) == (GoalStatus.SUCCEEDED, {"success": False, "message": "",
                                                                           "steps": 0})
        server.close()  # the goals never started are aborted, and close returns in bounded time
        assert server.statistics().running == 0
        t.close()


def test_feedback_callback_is_bounded_and_off_the_server_thread() -> None:
    gate = threading.Event()
    threads: list[str] = []

    def slow_callback(fb: dict[str, Any]) -> None:
        threads.append(threading.current_thread().name)
        gate.wait(5.0)

    def execute(h: GoalHandle) -> dict[str, Any]:
        for i in range(goal_serving.FEEDBACK_QUEUE_DEPTH + 20):
            h.publish_feedback({"step": i})
        return {"success": True}

    with MemoryTransport() as t:
        t.create_action_server("arm", VLA, execute)
        goal = t.send_goal("arm", VLA, {"task": "x"}, feedback=slow_callback)
        assert goal.result(5.0)[0] == GoalStatus.SUCCEEDED  # the result does not wait for the callback
        gate.set()
        assert wait_for(lambda: goal.feedback_received == goal_serving.FEEDBACK_QUEUE_DEPTH + 20)
        assert goal.feedback_dropped >= 1
        assert wait_for(lambda: bool(threads)), (threads, goal.feedback_received, goal.feedback_dropped)
        assert threads[0].startswith("goal-feedback:")
        t.close()


def test_a_raising_feedback_callback_does_not_break_the_goal() -> None:
    def boom(fb: dict[str, Any]) -> None:
        raise ValueError("bad callback")

    with MemoryTransport() as t:
        t.create_action_server("arm", VLA, lambda h: (h.publish_feedback({"step": 1}), {"success": True})[1])
        goal = t.send_goal("arm", VLA, {"task": "x"}, feedback=boom)
        assert goal.result(5.0)[0] == GoalStatus.SUCCEEDED
        time.sleep(0.05)
        t.close()


def test_readme_goals_example_runs_as_written() -> None:
    import re  # noqa: PLC0415
    from pathlib import Path  # noqa: PLC0415

    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    block = next(b for b in re.findall(r"```python\n(.*?)```", readme, flags=re.S)
                 if "create_action_server(\"arm\"" in b)
    namespace: dict[str, Any] = {}
    exec(compile(block, "README.md", "exec"), namespace)
    assert namespace["status"] == GoalStatus.SUCCEEDED
    assert namespace["result"] == {"success": True, "message": "", "steps": 3}


def test_a_goal_whose_acceptance_times_out_is_cancelled() -> None:
    """accept() slower than the sender's timeout: the sender gets RequestTimeoutError, the goal does not run on."""
    release = threading.Event()
    ran: list[bool] = []

    def slow_accept(goal: dict[str, Any]) -> bool:
        release.wait(5.0)
        return True

    def execute(h: GoalHandle) -> dict[str, Any]:
        ran.append(h.wait_for_cancel(5.0))  # True: woken by the cancel, not by the timeout
        return {}

    with MemoryTransport() as t:
        server = t.create_action_server("arm", VLA, execute, accept=slow_accept)
        threading.Timer(0.3, release.set).start()
        with pytest.raises(RequestTimeoutError, match="arm"):
            t.send_goal("arm", VLA, {"task": "x"}, timeout=0.1)
        # The cancel came while accept() ran: the goal is refused when decided, and never runs.
        assert wait_for(lambda: server.statistics().rejected == 1, timeout=5.0)
        assert server.statistics().accepted == 0 and ran == []
        t.close()


def test_inline_feedback_runs_on_the_driver_thread_in_order_and_a_raising_one_is_contained() -> None:
    # feedback_inline=True: no queue, no goal-feedback thread; on memory the driver's thread is the
    # server's goal thread. Every message comes, in order, before the result; a raising callback is logged.
    threads: list[str] = []
    steps: list[int] = []

    def callback(fb: dict[str, Any]) -> None:
        threads.append(threading.current_thread().name)
        steps.append(fb["step"])
        if fb["step"] == 3:
            raise ValueError("bad callback")

    def execute(h: GoalHandle) -> dict[str, Any]:
        for i in range(goal_serving.FEEDBACK_QUEUE_DEPTH + 20):
            h.publish_feedback({"step": i})
        return {"success": True}

    with MemoryTransport() as t:
        t.create_action_server("arm", VLA, execute)
        goal = t.send_goal("arm", VLA, {"task": "x"}, feedback=callback, feedback_inline=True)
        assert goal.result(5.0)[0] == GoalStatus.SUCCEEDED
        assert steps == list(range(goal_serving.FEEDBACK_QUEUE_DEPTH + 20))  # nothing dropped, none after the result
        assert goal.feedback_dropped == 0
        assert threads and all(name.startswith("arm:goal:") for name in threads), set(threads)
        t.close()
