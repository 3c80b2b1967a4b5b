"""``examples/vla_sim_arm.py`` against the LeRobot-protocol test policy server (gRPC on 127.0.0.1).

On memory the example sends its own task (``--task``) and prints the result and the arm's pose;
on each cross-process transport (the ``recipe_transport`` fixture: Zenoh on loopback with
multicast scouting off, ROS 2 in a private domain) it serves goals, and this process sends the
goal and reads the arm's joint states over the transport. The policy reaches for a pose beyond
the elbow's limit: the arm must end at the shoulder's target and at the elbow's limit.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("grpc", reason="the vla extra (grpcio) is not installed")

from agents_core import Topic
from agents_core.errors import RequestTimeoutError, ServiceUnavailableError
from agents_core.testing.helpers import wait_for
from agents_core.testing.pairs import skip_unless_installed
from agents_core.testing.recipes import RecipeTransport, run_recipe
from agents_core.transport.goals import GoalStatus
from tests.servers.policy_server import PolicyTestServer, ReachPolicy

from .test_examples import EXAMPLES, _run_example

#: Beyond the example's elbow limit (-0.3): the commands are clipped there.
TARGET = {"shoulder": 0.8, "elbow": -0.5}


def test_vla_reaches_within_its_limits_on_memory() -> None:
    with PolicyTestServer(ReachPolicy(TARGET, step=0.05)) as server:
        out = _run_example("vla_sim_arm.py", "--policy-port", str(server.port), "--task", "reach the cup",
                           "--once", "--seconds", "120")
        assert server.setups and server.observations  # the example really asked the policy
    assert "result: SUCCEEDED after 80 steps" in out, out
    assert "arm at: shoulder=0.800, elbow=-0.300" in out, out


def test_vla_serves_goals_on_cross_process_transports(recipe_transport: RecipeTransport, tmp_path: Path) -> None:
    if recipe_transport.name == "ros2":
        skip_unless_installed("ros2", "agents_interfaces")
    with PolicyTestServer(ReachPolicy(TARGET, step=0.05)) as server, \
            run_recipe(EXAMPLES / "vla_sim_arm.py", recipe_transport, tmp_path,
                       ["--policy-port", str(server.port), "--seconds", "300"], ready_timeout=90):
        user = recipe_transport.open_asker()
        states: list[Any] = []
        lock = threading.Lock()

        def got(state: Any) -> None:
            with lock:
                states.append(state)

        sub = user.create_subscription(Topic("joint_states", "JointState"), got)
        try:
            assert wait_for(lambda: len(states) > 5, timeout=30), "no joint states from the example's arm"
            deadline = time.monotonic() + 30
            while True:  # discovery of the action server may take a moment on a network transport
                try:
                    goal = user.send_goal("arm_vla", "VisionLanguageAction", {"task": "reach", "max_steps": 80},
                                          timeout=5.0)
                    break
                except (ServiceUnavailableError, RequestTimeoutError):
                    if time.monotonic() > deadline:
                        raise
                    time.sleep(0.2)
            status, result = goal.result(timeout=60)
            assert status == GoalStatus.SUCCEEDED, result
            assert result["steps"] == 80
            time.sleep(0.3)  # a few states after the last command
            with lock:
                final = dict(zip(states[-1].name, states[-1].position, strict=True))
        finally:
            sub.close()
    assert final["shoulder"] == pytest.approx(0.8, abs=1e-6)
    assert final["elbow"] == pytest.approx(-0.3, abs=1e-6)
