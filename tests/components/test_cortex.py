"""Cortex on the memory transport: planning and execution against a scripted model server and a fake robot.

The planner model is a real HTTP server (:class:`tests.servers.scripted_chat_server.ScriptedChatServer`)
replaying tool calls; the robot is a navigation action server that moves a pose and an arm with
``@component_action`` methods. Bad input: a plan naming a tool that does not exist or with
arguments that do not fit, a confirmation server that hangs, an unparseable confirmation, a
component failing mid-task, a cancel mid-plan.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest

from agents_core.actions import Action, component_action
from agents_core.clients.generic import GenericHTTPClient
from agents_core.components import Component, Cortex
from agents_core.config import CortexConfig
from agents_core.errors import ConfigError
from agents_core.launch.launcher import Launcher
from agents_core.models import GenericLLM
from agents_core.status import HealthStatus
from agents_core.transport.goals import ACTION_TYPES, ActionType, GoalStatus, register_action_type
from tests.servers.ollama_server import Fault
from tests.servers.scripted_chat_server import ScriptedChatServer, calls, text

if "NavigateToPose" not in ACTION_TYPES:
    register_action_type(ActionType(
        name="NavigateToPose", goal={"x": "float", "y": "float"},
        result={"success": "bool", "message": "str"}, feedback={"x": "float", "y": "float"}))


class FakeNavigation(Component):
    """Moves a pose toward each goal's (x, y) in small steps, with feedback; stops on cancel."""

    _action_type = "NavigateToPose"

    def __init__(self, step_time: float = 0.01, **kwargs: Any) -> None:
        kwargs.setdefault("component_name", "nav")
        super().__init__(trigger=None, run_type="ActionServer", **kwargs)
        self.pose = [0.0, 0.0]
        self.step_time = step_time
        self.goals: list[dict[str, Any]] = []
        self.canceled_goals = 0

    @classmethod
    def _server_capable(cls) -> bool:
        return True

    def main_action_callback(self, goal_handle: Any) -> dict[str, Any]:
        self.goals.append(dict(goal_handle.goal))
        target = [goal_handle.goal["x"], goal_handle.goal["y"]]
        for _ in range(10):
            if goal_handle.wait_for_cancel(self.step_time):
                self.canceled_goals += 1
                goal_handle.canceled()
                return {"success": False, "message": "canceled"}
            self.pose = [p + (t - p) * 0.5 for p, t in zip(self.pose, target, strict=True)]
            goal_handle.publish_feedback({"x": self.pose[0], "y": self.pose[1]})
        self.pose = target
        return {"success": True, "message": f"arrived at {target}"}

    def _execution_step(self, **kwargs: Any) -> None:
        pass


class FakeArm(Component):
    """An arm with actions the planner may call."""

    def __init__(self, **kwargs: Any) -> None:
        kwargs.setdefault("component_name", "arm")
        super().__init__(trigger=0.1, **kwargs)
        self.grasped: list[str] = []

    @component_action(description={
        "description": "Grasp an object by name.",
        "parameters": {"type": "object", "properties": {"object": {"type": "string"}}, "required": ["object"]}})
    def grasp(self, object: str) -> str:
        self.grasped.append(object)
        return f"holding {object}"

    @component_action(description={
        "description": "Say what is in front of the arm.",
        "parameters": {"type": "object", "properties": {}, "required": []}})
    def look(self) -> str:
        return "a red cup"

    def _execution_step(self, **kwargs: Any) -> None:
        pass


LED: list[str] = []


def toggle_led() -> None:
    """Toggle the robot's LED."""
    LED.append("toggled")


def _client(server: ScriptedChatServer, timeout: float = 10.0) -> GenericHTTPClient:
    return GenericHTTPClient(GenericLLM(name="planner", checkpoint="planner"), port=server.port,
                             inference_timeout=timeout)


def _cortex(server: ScriptedChatServer, **config: Any) -> Cortex:
    settings: dict[str, Any] = {"action_servers": {"nav": "NavigateToPose"}, "monitoring_interval": 0.05,
                                "confirmation_timeout": 5.0, "max_planning_steps": 4, "max_execution_steps": 4}
    settings.update(config)
    return Cortex(actions=[Action(toggle_led)], model_client=_client(server), config=CortexConfig(**settings),
                  component_name="cortex")


@pytest.fixture
def robot() -> Iterator[tuple[FakeNavigation, FakeArm]]:
    LED.clear()
    yield FakeNavigation(), FakeArm()


def _run(server: ScriptedChatServer, robot: tuple[FakeNavigation, FakeArm], task: str, timeout: float = 20.0,
         during: Any = None, **config: Any) -> tuple[GoalStatus, dict[str, Any], list[str], Cortex]:
    cortex = _cortex(server, **config)
    feedback: list[str] = []
    launcher = Launcher("memory")
    launcher.add_pkg(components=[*robot, cortex])
    with launcher:
        goal = launcher.transport.send_goal("cortex", "VisionLanguageAction", {"task": task},
                                            feedback=lambda f: feedback.append(f["status"]), timeout=5.0)
        assert goal.accepted
        if during is not None:
            during(goal, cortex)
        status, result = goal.result(timeout)
    return status, result, feedback, cortex


def test_plan_runs_actions_goals_and_component_actions_in_order(robot: Any) -> None:
    nav, arm = robot
    with ScriptedChatServer(plan=[
        calls(("inspect_component", {"component": "arm"})),
        calls(("nav.send_goal", {"x": 2.0, "y": 1.0}), ("arm.grasp", {"object": "<result of step 1>"}),
              ("toggle_led", {})),
        text("The cup is in hand."),
    ], confirm=[text("EXECUTE"), text("CONTINUE: the robot is still driving"),
                calls(("arm.grasp", {"object": "cup"}), answer="EXECUTE"), text("EXECUTE")]) as server:
        status, result, feedback, cortex = _run(server, robot, "fetch the cup")
    assert status == GoalStatus.SUCCEEDED, result
    assert result["success"] and result["steps"] == 3
    assert nav.pose == [2.0, 1.0] and nav.goals == [{"x": 2.0, "y": 1.0}]
    # The confirmation rewrote the placeholder from the planner with the real argument.
    assert arm.grasped == ["cup"]
    assert LED == ["toggled"]
    assert "inspect_component" in str(server.planning_requests[1]["messages"])
    assert "FakeArm" in str(server.planning_requests[1]["messages"])
    # Each step's outcome goes back to the planner.
    assert "holding cup" in str(server.planning_requests[2]["messages"])
    assert any("plan: nav.send_goal, arm.grasp, toggle_led" in f for f in feedback)
    assert cortex.component_health()["nav"]["health"] == "HEALTHY"
    tools = {t["function"]["name"] for t in server.planning_requests[0]["tools"]}
    assert {"inspect_component", "arm.grasp", "arm.look", "nav.send_goal", "toggle_led"} <= tools


def test_answer_without_actions_succeeds_with_the_text(robot: Any) -> None:
    with ScriptedChatServer(plan=[text("<think>hm</think>I am a robot.")]) as server:
        status, result, _, _ = _run(server, robot, "who are you")
    assert status == GoalStatus.SUCCEEDED and result["message"] == "I am a robot."


def test_invented_tool_is_never_dispatched_and_the_planner_is_told(robot: Any) -> None:
    nav, arm = robot
    with ScriptedChatServer(plan=[
        calls(("arm.grasp", {"object": "cup"}), ("arm.fly", {})),          # a tool that does not exist
        calls(("arm.grasp", {"object": 42})),                               # an argument of the wrong type
        calls(("arm.grasp", {"object": "cup", "force": "max"})),            # an argument it does not take
        calls(("nav.send_goal", {"x": "far"})),                            # a goal field of the wrong kind
    ]) as server:
        status, result, _, _ = _run(server, robot, "grasp", max_planning_steps=4)
    assert status == GoalStatus.ABORTED
    assert "max_planning_steps" in result["message"]
    assert arm.grasped == [] and nav.goals == []          # nothing of a refused plan ran
    second = str(server.planning_requests[1]["messages"])
    assert "no tool named 'arm.fly'" in second and "refused" in second
    assert "must be of type string" in str(server.planning_requests[2]["messages"])
    assert "unknown field 'force'" in str(server.planning_requests[3]["messages"])
    assert server.confirmation_requests == []


def test_invented_tool_then_a_valid_plan_runs_only_the_valid_one(robot: Any) -> None:
    _, arm = robot
    with ScriptedChatServer(plan=[calls(("arm.teleport", {})), calls(("arm.grasp", {"object": "cup"})),
                                  text("done")]) as server:
        status, _, _, _ = _run(server, robot, "grasp")
    assert status == GoalStatus.SUCCEEDED and arm.grasped == ["cup"]


def test_confirmation_that_hangs_aborts(robot: Any) -> None:
    _, arm = robot
    with ScriptedChatServer(plan=[calls(("arm.grasp", {"object": "cup"}))], confirm=[{"hang": 5.0}]) as server:
        started = time.monotonic()
        status, result, _, _ = _run(server, robot, "grasp", confirmation_timeout=0.5)
    assert status == GoalStatus.ABORTED
    assert "did not answer within 0.5 s" in result["message"]
    assert time.monotonic() - started < 4.5
    assert arm.grasped == []


@pytest.mark.parametrize("answer", [text("Sure, sounds good"), text(""), calls(("arm.look", {})),
                                    calls(("arm.grasp", {"object": 3})), calls(("arm.grasp", "{not json"))])
def test_unparseable_or_invalid_confirmation_aborts(robot: Any, answer: dict[str, Any]) -> None:
    _, arm = robot
    with ScriptedChatServer(plan=[calls(("arm.grasp", {"object": "cup"}))], confirm=[answer]) as server:
        status, result, _, _ = _run(server, robot, "grasp")
    assert status == GoalStatus.ABORTED, result
    assert "not confirmed" in result["message"]
    assert arm.grasped == []


def test_confirmation_server_error_aborts(robot: Any) -> None:
    _, arm = robot
    with ScriptedChatServer(plan=[calls(("arm.grasp", {"object": "cup"}))]) as server:
        server.add_fault(Fault(
            path="/v1/chat/completions", kind="status", status=500, times=None))
        status, _, _, _ = _run(server, robot, "grasp")
    assert status == GoalStatus.ABORTED and arm.grasped == []


def test_skip_and_abort_decisions(robot: Any) -> None:
    _, arm = robot
    with ScriptedChatServer(plan=[calls(("arm.grasp", {"object": "a"}), ("arm.grasp", {"object": "b"}),
                                        ("arm.grasp", {"object": "c"}))],
                            confirm=[text("SKIP: not needed"), text("EXECUTE"), text("ABORT: the cup fell")]) as server:
        status, result, _, _ = _run(server, robot, "grasp three")
    assert status == GoalStatus.ABORTED and "the cup fell" in result["message"]
    assert arm.grasped == ["b"]


def test_dependent_component_failing_mid_task_aborts_and_cancels_its_goal(robot: Any) -> None:
    nav, _ = robot
    nav.step_time = 0.5   # a long drive

    def fail_nav(goal: Any, cortex: Cortex) -> None:
        deadline = time.monotonic() + 5
        while not nav.goals and time.monotonic() < deadline:
            time.sleep(0.01)
        nav._set_health(HealthStatus.COMPONENT_FAILURE, "wheel motor stalled")

    with ScriptedChatServer(plan=[calls(("nav.send_goal", {"x": 5.0, "y": 0.0}), ("toggle_led", {}))],
                            confirm=[text("EXECUTE"), text("CONTINUE")]) as server:
        status, result, _, _ = _run(server, robot, "drive", during=fail_nav)
    assert status == GoalStatus.ABORTED
    assert "wheel motor stalled" in result["message"] and "goals canceled on nav" in result["message"]
    assert nav.canceled_goals == 1 and LED == []


def test_cancel_mid_plan_stops_and_cancels_running_goals(robot: Any) -> None:
    nav, arm = robot
    nav.step_time = 0.5

    def cancel_when_driving(goal: Any, cortex: Cortex) -> None:
        deadline = time.monotonic() + 5
        while not nav.goals and time.monotonic() < deadline:
            time.sleep(0.01)
        assert goal.cancel(5.0)

    with ScriptedChatServer(plan=[calls(("nav.send_goal", {"x": 5.0, "y": 0.0}), ("arm.grasp", {"object": "x"}))],
                            confirm=[text("EXECUTE"), text("CONTINUE")]) as server:
        status, _, _, cortex = _run(server, robot, "drive then grasp", during=cancel_when_driving)
    assert status == GoalStatus.CANCELED
    assert nav.canceled_goals == 1 and arm.grasped == []
    assert cortex.tasks["canceled"] == 1


def test_continue_with_nothing_running_aborts(robot: Any) -> None:
    with ScriptedChatServer(plan=[calls(("toggle_led", {}))], confirm=[text("CONTINUE")]) as server:
        status, result, _, _ = _run(server, robot, "led")
    assert status == GoalStatus.ABORTED and "nothing is running" in result["message"]
    assert LED == []


def test_planner_down_aborts_with_the_reason(robot: Any) -> None:
    with ScriptedChatServer(plan=[{"hang": 5.0}]) as server:
        cortex_timeout = 1.0
        cortex = Cortex(model_client=_client(server, timeout=cortex_timeout),
                        config=CortexConfig(max_planning_steps=2), component_name="cortex")
        launcher = Launcher("memory")
        launcher.add_pkg(components=[*robot, cortex])
        with launcher:
            goal = launcher.transport.send_goal("cortex", "VisionLanguageAction", {"task": "x"}, timeout=5.0)
            status, result = goal.result(15.0)
    assert status == GoalStatus.ABORTED and "planner model failed" in result["message"]


def test_plan_iterations_are_bounded(robot: Any) -> None:
    with ScriptedChatServer(plan=[calls(("toggle_led", {}))] * 10) as server:
        status, result, _, _ = _run(server, robot, "blink forever", max_execution_steps=3)
    assert status == GoalStatus.ABORTED and "max_execution_steps" in result["message"]
    assert LED == ["toggled"] * 3


def test_second_task_while_one_runs_is_rejected(robot: Any) -> None:
    nav, _ = robot
    nav.step_time = 0.2
    rejected = threading.Event()

    def second(goal: Any, cortex: Cortex) -> None:
        other = cortex.transport.send_goal("cortex", "VisionLanguageAction", {"task": "other"}, timeout=5.0)
        if other.status == GoalStatus.REJECTED:
            rejected.set()

    with ScriptedChatServer(plan=[calls(("nav.send_goal", {"x": 1.0, "y": 1.0}))]) as server:
        status, _, _, _ = _run(server, robot, "drive", during=second)
    assert rejected.is_set() and status == GoalStatus.SUCCEEDED


def test_construction_checks() -> None:
    with ScriptedChatServer() as server:
        with pytest.raises(ConfigError, match="needs a description"):
            Cortex(actions=[Action(lambda: None)], model_client=_client(server))   # no description
        with pytest.raises(Exception, match="takes no 'inputs'"):
            Cortex(inputs=[], model_client=_client(server))
        with pytest.raises(Exception, match="needs a model_client"):
            Cortex()
