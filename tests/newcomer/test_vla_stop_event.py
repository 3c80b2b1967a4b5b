"""Item 1 of issue 38: ``VLA.set_termination_trigger("event", stop_event=...)`` called before the launch, as
upstream's recipes do, ends the goal when the event's topic says so: in the launcher's process (memory) and
with the VLA in a process of its own (Zenoh, ``multiprocessing=True``)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("grpc", reason="the vla extra (grpcio) is not installed")

from agents_core.errors import RequestTimeoutError, ServiceUnavailableError
from agents_core.events import Event
from agents_core.launch.launcher import Launcher
from agents_core.testing.helpers import wait_for
from agents_core.testing.recipes import open_recipe_transport, run_recipe
from agents_core.transport.goals import GoalStatus
from tests.components import vla_recipe
from tests.components.sim_arm import SimulatedArm
from tests.newcomer.vla_stop_recipe import DONE
from tests.servers.policy_server import PolicyTestServer, ReachPolicy

REPO = Path(__file__).resolve().parents[2]
FAR = {"shoulder": 1.9, "elbow": 0.9}


def _run_goal_and_stop(user: Any) -> tuple[Any, dict[str, Any], int]:
    """Send a long goal, publish ``arm_done`` True after some feedback; the goal's status and result."""
    arm = SimulatedArm(user, {"shoulder": 0.0, "elbow": 0.0}, state_topic=vla_recipe.STATE,
                       command_topic=vla_recipe.COMMANDS, camera_topic=vla_recipe.CAMERA)
    done = user.create_publisher(DONE)
    feedback: list[dict[str, Any]] = []
    try:
        time.sleep(0.5)
        deadline = time.monotonic() + 20
        while True:
            try:
                goal = user.send_goal("arm_vla", "VisionLanguageAction", {"task": "reach", "max_steps": 100_000},
                                      feedback=feedback.append, timeout=5.0)
                break
            except (ServiceUnavailableError, RequestTimeoutError):
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.2)
        assert wait_for(lambda: len(feedback) >= 5, 15.0)
        done.publish(False)  # the condition is false: nothing ends
        time.sleep(0.3)
        steps_before = len(feedback)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:  # published until the goal ends (the first may precede matching)
            done.publish(True)
            if goal.done:
                break
            time.sleep(0.2)
        status, result = goal.result(timeout=15)
        return status, result, steps_before
    finally:
        done.close()
        arm.close()


def test_event_set_before_the_launch_ends_the_goal_on_memory() -> None:
    with PolicyTestServer(ReachPolicy(FAR, step=0.01)) as server:
        vla = vla_recipe.build(server.port)
        vla.set_termination_trigger("event", stop_event=Event(DONE.msg.data == True))  # noqa: E712
        launcher = Launcher("memory")
        launcher.add_pkg(components=[vla])
        with launcher:
            status, result, before = _run_goal_and_stop(launcher.transport)
    assert status == GoalStatus.SUCCEEDED, result
    assert result["message"] == "the termination event fired"
    assert before <= result["steps"] < 100_000


@pytest.mark.zenoh
def test_event_reaches_a_vla_in_its_own_process(tmp_path: Path) -> None:
    pytest.importorskip("zenoh")
    transport = open_recipe_transport("zenoh")
    try:
        with PolicyTestServer(ReachPolicy(FAR, step=0.01)) as server, \
                run_recipe("tests.newcomer.vla_stop_recipe", transport, tmp_path,
                           ["--policy-port", str(server.port), "--multiprocessing"], cwd=REPO):
            status, result, _ = _run_goal_and_stop(transport.open_asker())
    finally:
        transport.close()
    assert status == GoalStatus.SUCCEEDED, result
    assert result["message"] == "the termination event fired"
