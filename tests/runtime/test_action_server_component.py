"""ACTION_SERVER components on the memory transport: goals served while active, aborted on deactivate."""

from __future__ import annotations

import threading
from typing import Any

from agents_core.components import Component
from agents_core.transport import MemoryTransport
from agents_core.transport.goals import GoalHandle, GoalStatus
from tests.conftest import wait_for

VLA = "VisionLanguageAction"


class Mover(Component):
    """A tiny action server: counts steps until max_steps or a cancel."""

    _action_type = VLA

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(trigger=None, run_type="ActionServer", **kwargs)
        self.goal_threads: list[str] = []

    def _accept_goal(self, goal: dict[str, Any]) -> bool:
        return bool(goal["task"])

    def main_action_callback(self, goal_handle: GoalHandle) -> dict[str, Any]:
        self.goal_threads.append(threading.current_thread().name)
        step = 0
        while step < goal_handle.goal["max_steps"] and not goal_handle.wait_for_cancel(0.01):
            step += 1
            goal_handle.publish_feedback({"step": step, "action": [0.5 * step], "status": "moving"})
        return {"success": not goal_handle.cancel_requested, "steps": step}


def _bound(component: Component) -> MemoryTransport:
    transport = MemoryTransport()
    component.runtime.bind(transport)
    component.configure()
    component.activate()
    return transport


def test_component_serves_goals_only_while_active() -> None:
    mover = Mover(component_name="mover")
    transport = _bound(mover)
    try:
        assert mover.action_name == "mover"
        feedback: list[dict[str, Any]] = []
        goal = transport.send_goal("mover", VLA, {"task": "reach", "max_steps": 4}, feedback=feedback.append)
        assert goal.result(5.0) == (GoalStatus.SUCCEEDED, {"success": True, "message": "", "steps": 4})
        assert wait_for(lambda: len(feedback) == 4)
        assert mover.goal_threads[0].startswith("mover:goal:")  # not the step worker
        rejected = transport.send_goal("mover", VLA, {"task": ""})
        assert rejected.result(1.0)[0] == GoalStatus.REJECTED

        long_goal = transport.send_goal("mover", VLA, {"task": "reach", "max_steps": 100000})
        assert wait_for(lambda: long_goal.status == GoalStatus.EXECUTING)
        mover.deactivate()
        status, result = long_goal.result(5.0)
        assert status == GoalStatus.ABORTED and "closed" in result["message"]
        late = None
        try:
            late = transport.send_goal("mover", VLA, {"task": "reach"}, timeout=0.5)
        except Exception as exc:  # nobody serves the action while inactive
            assert "no action server" in str(exc)
        assert late is None
        mover.activate()
        again = transport.send_goal("mover", VLA, {"task": "reach", "max_steps": 2})
        assert again.result(5.0)[0] == GoalStatus.SUCCEEDED
    finally:
        mover.shutdown()
        transport.close()


def test_closing_the_transport_aborts_goals_on_both_sides() -> None:
    mover = Mover(component_name="mover2")
    transport = _bound(mover)
    goal = transport.send_goal("mover2", VLA, {"task": "reach", "max_steps": 100000})
    assert wait_for(lambda: goal.status == GoalStatus.EXECUTING)
    transport.close()
    status, result = goal.result(5.0)
    assert status == GoalStatus.ABORTED and result["message"]
    mover.shutdown()
