"""ROS 2 actions between our rmw_zenoh transport and a peer that shares none of our code (``raw_action_peer.py``:
zenoh-python + rosbags + xxhash, the action's types written from its ``.action`` file), both ways."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from .conftest import rmw_options

pytest.importorskip("rosbags", reason="needs the rmw_zenoh extra")

from agents_core.errors import ServiceUnavailableError
from agents_core.transport.goals import GoalHandle, GoalStatus
from agents_zenoh.rmw.goals import RESULT_QUERY_S
from agents_zenoh.rmw.transport import RmwZenohTransport

pytestmark = pytest.mark.zenoh

PEER = Path(__file__).parent / "raw_action_peer.py"


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}


def test_a_raw_ros_client_drives_our_action_server(router: str) -> None:
    transport = RmwZenohTransport(**rmw_options(router))
    try:
        def execute(handle: GoalHandle) -> dict[str, Any]:
            for step in range(handle.goal["max_steps"]):
                handle.publish_feedback({"step": step, "action": [float(step)], "status": "ours"})
                time.sleep(0.05)
            return {"success": True, "message": f"did {handle.goal['task']}", "steps": handle.goal["max_steps"]}

        server = transport.create_action_server("arm/raw_client", "VisionLanguageAction", execute)
        done = subprocess.run([sys.executable, str(PEER), router, "21", "client", "arm/raw_client"],
                              capture_output=True, text=True, timeout=90, env=_env(), check=False)
        assert done.returncode == 0, done.stderr[-2000:]
        out = json.loads(done.stdout.strip().splitlines()[-1])
        assert out == {"accepted": True, "send_echoed": True, "status": 4, "success": True, "message": "did raw",
                       "steps": 3, "result_echoed": True, "feedback": [0, 1, 2]}
        stats = server.statistics()
        assert (stats.accepted, stats.succeeded, stats.decode_errors) == (1, 1, 0)
        server.close()
    finally:
        transport.close()


def _send(transport: RmwZenohTransport, name: str, task: str, feedback: list[dict[str, Any]]) -> Any:
    deadline = time.monotonic() + 10.0
    while True:
        try:
            return transport.send_goal(name, "VisionLanguageAction", {"task": task}, feedback=feedback.append,
                                       timeout=5.0)
        except ServiceUnavailableError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)


@contextmanager
def _raw_server(router: str, name: str) -> Iterator[subprocess.Popen[str]]:
    proc = subprocess.Popen([sys.executable, str(PEER), router, "21", "serve", name],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=_env())
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "ready"
        yield proc
    finally:
        assert proc.stdin is not None
        proc.stdin.close()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        if proc.stdout is not None:
            proc.stdout.close()


def test_our_goal_client_on_a_raw_ros_action_server(router: str) -> None:
    transport = RmwZenohTransport(**rmw_options(router))
    try:
        with _raw_server(router, "arm/raw_server"):
            feedback: list[dict[str, Any]] = []
            goal = _send(transport, "arm/raw_server", "wave", feedback)
            assert goal.accepted
            status, result = goal.result(10.0)
            assert status == GoalStatus.SUCCEEDED
            assert result == {"success": True, "message": "raw did wave", "steps": 3}
            assert [f["step"] for f in feedback] == [0, 1, 2]
            assert feedback[1] == {"step": 1, "action": [1.0, 0.5], "status": "raw moving"}
    finally:
        transport.close()


def test_a_raw_server_killed_mid_goal_aborts_our_goal(router: str) -> None:
    transport = RmwZenohTransport(**rmw_options(router))
    try:
        with _raw_server(router, "arm/raw_dies") as proc:
            goal = _send(transport, "arm/raw_dies", "hang", [])
            assert goal.accepted
            time.sleep(RESULT_QUERY_S + 0.5)  # past one result query: the goal is still followed
            assert not goal.done
            proc.kill()
            status, result = goal.result(15.0)
            assert status == GoalStatus.ABORTED and "went away" in result["message"], (status, result)
    finally:
        transport.close()


def test_a_goal_longer_than_one_result_query_gets_its_result(router: str) -> None:
    server_side = RmwZenohTransport(**rmw_options(router))
    client_side = RmwZenohTransport(**rmw_options(router))
    try:
        server = server_side.create_action_server(
            "arm/slow", "VisionLanguageAction",
            lambda handle: (time.sleep(RESULT_QUERY_S * 1.5), {"success": True, "message": "slow", "steps": 1})[1])
        goal = _send(client_side, "arm/slow", "slow", [])
        assert goal.result(15.0) == (GoalStatus.SUCCEEDED, {"success": True, "message": "slow", "steps": 1})
        server.close()
    finally:
        client_side.close()
        server_side.close()


def test_cancel_codes_and_status_as_rcl_action_has_them(router: str) -> None:
    from agents_zenoh.rmw import actions  # noqa: PLC0415

    server_side = RmwZenohTransport(**rmw_options(router))
    client_side = RmwZenohTransport(**rmw_options(router))
    try:
        def execute(handle: GoalHandle) -> dict[str, Any]:
            if handle.goal["task"] == "quick":
                return {"success": True}
            handle.wait_for_cancel(20.0)
            return {"success": False, "message": "canceled"}

        server = server_side.create_action_server("arm/cancels", "VisionLanguageAction", execute)
        quick = _send(client_side, "arm/cancels", "quick", [])
        assert quick.result(10.0)[0] == GoalStatus.SUCCEEDED
        goals = [_send(client_side, "arm/cancels", "long", []) for _ in range(2)]
        deadline = time.monotonic() + 5.0
        while any(g.status != GoalStatus.EXECUTING for g in goals) and time.monotonic() < deadline:
            time.sleep(0.02)
        assert [g.status for g in goals] == [GoalStatus.EXECUTING] * 2  # read from the status topic

        def cancel(goal_id: str) -> Any:
            return client_side.driver.ros_request("/arm/cancels/_action/cancel_goal", actions.CANCEL_GOAL,
                                                  actions.cancel_request(goal_id), 5.0)

        assert cancel(quick.goal_id).return_code == 3  # GOAL_TERMINATED
        assert cancel("12" * 16).return_code == 2  # UNKNOWN_GOAL_ID
        everything = cancel("0" * 32)  # the zero id: every running goal
        assert everything.return_code == 0
        assert sorted(actions.uuid_hex(info.goal_id) for info in everything.goals_canceling) == sorted(
            g.goal_id for g in goals)
        assert [g.result(10.0)[0] for g in goals] == [GoalStatus.CANCELED] * 2
        server.close()
    finally:
        client_side.close()
        server_side.close()
