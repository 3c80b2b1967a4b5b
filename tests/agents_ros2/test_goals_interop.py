"""A VLA-type action-server component on ROS 2, driven by a plain rclpy ActionClient in another process."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("rclpy", reason="needs the ros2 extra")
pytest.importorskip("agents_interfaces", reason="needs agents_interfaces (pip install --no-build-isolation "
                                                "./interfaces)")

from agents_core.components import Component
from agents_core.testing.pairs import private_ros_environment
from agents_core.transport.goals import GoalHandle, GoalStatus

pytestmark = [pytest.mark.ros2, pytest.mark.slow]

REPO = Path(__file__).resolve().parents[2]
CLIENT = Path(__file__).with_name("plain_action_client.py")


class Mover(Component):
    """Counts steps until max_steps or a cancel, with feedback; rejects an empty task."""

    _action_type = "VisionLanguageAction"

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(trigger=None, run_type="ActionServer", **kwargs)

    def _accept_goal(self, goal: dict[str, Any]) -> bool:
        return bool(goal["task"])

    def main_action_callback(self, goal_handle: GoalHandle) -> dict[str, Any]:
        step = 0
        while step < goal_handle.goal["max_steps"] and not goal_handle.wait_for_cancel(0.02):
            step += 1
            goal_handle.publish_feedback({"step": step, "action": [0.5 * step, 1.0], "status": "moving"})
        return {"success": not goal_handle.cancel_requested, "message": goal_handle.goal["task"], "steps": step}


def test_plain_rclpy_action_client_drives_a_component() -> None:
    from agents_ros2.transport import Ros2Transport  # noqa: PLC0415

    domain_id = private_ros_environment()
    transport = Ros2Transport(domain_id=domain_id)
    name = f"mover_{os.getpid()}"
    mover = Mover(component_name=name)
    proc = None
    try:
        mover.runtime.bind(transport)
        mover.configure()
        mover.activate()
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain_id), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
        proc = subprocess.Popen([sys.executable, str(CLIENT), "--action", f"/{name}"], cwd=REPO, env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        out, err = proc.communicate(timeout=90)
        assert proc.returncode == 0, err + out
        seen = json.loads(out.strip().splitlines()[-1])
        assert seen["project_modules"] == []
        assert seen["accepted"] is True
        assert [f["step"] for f in seen["feedback"]] == [1, 2, 3]
        assert seen["feedback"][0] == {"step": 1, "action": [0.5, 1.0], "status": "moving"}
        assert seen["status"] == 4 and seen["result"] == {"success": True, "message": "reach", "steps": 3}
        assert seen["cancel_goals"] == 1 and seen["cancel_status"] == 5 and seen["cancel_success"] is False
        assert seen["rejected_accepted"] is False
    finally:
        if proc is not None and proc.poll() is None:
            proc.kill()
            proc.wait(10)
        mover.shutdown()
        transport.close()


def test_a_goal_accepted_after_its_sender_gave_up_is_cancelled() -> None:
    import time  # noqa: PLC0415

    from agents_core.errors import RequestTimeoutError  # noqa: PLC0415
    from agents_core.testing.pairs import ros2_pair  # noqa: PLC0415

    ran: list[bool] = []

    def slow_accept(goal: dict[str, Any]) -> bool:
        if goal["task"] == "slow":
            time.sleep(1.0)  # on the server's executor: the answer comes after the sender's timeout
        return True

    def execute(handle: GoalHandle) -> dict[str, Any]:
        if handle.goal["task"] == "slow":
            ran.append(handle.wait_for_cancel(10.0))
        return {}

    with ros2_pair() as (a, b):
        server = a.create_action_server(f"late_{os.getpid()}", "VisionLanguageAction", execute, accept=slow_accept)
        # Discovery first, with a goal accepted at once.
        assert b.send_goal(server.name, "VisionLanguageAction", {"task": "fast"}, timeout=10.0).result(10.0)[0] \
            == GoalStatus.SUCCEEDED
        started = time.monotonic()
        with pytest.raises(RequestTimeoutError):
            b.send_goal(server.name, "VisionLanguageAction", {"task": "slow"}, timeout=0.5)
        deadline = time.monotonic() + 15.0
        while server.statistics().canceled < 1 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert server.statistics().canceled == 1 and ran == [True]
        assert time.monotonic() - started < 15.0
