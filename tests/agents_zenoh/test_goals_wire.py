"""Goals on Zenoh from a plain zenoh + msgpack client in another process (docs/zenoh-wire-format.md)."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh")

from agents_core.testing.helpers import free_tcp_port, wait_for
from agents_core.transport.goals import GoalHandle
from agents_zenoh.transport import ZenohTransport

REPO = Path(__file__).resolve().parents[2]


def execute(handle: GoalHandle) -> dict[str, Any]:
    step = 0
    while step < handle.goal["max_steps"] and not handle.wait_for_cancel(0.02):
        step += 1
        handle.publish_feedback({"step": step, "action": [0.25 * step, -1.0], "status": "moving"})
    return {"success": not handle.cancel_requested, "message": handle.goal["task"], "steps": step}


def test_plain_zenoh_client_sends_cancels_and_reads_results() -> None:
    port = free_tcp_port()
    server_side = ZenohTransport(mode="peer", listen=[f"tcp/127.0.0.1:{port}"], connect=[],
                                 multicast_scouting=False)
    proc = None
    try:
        server = server_side.create_action_server("arm_goal", "VisionLanguageAction", execute)
        proc = subprocess.Popen(
            [sys.executable, str(REPO / "tests" / "agents_zenoh" / "raw_goal_client.py"),
             "--connect", f"tcp/127.0.0.1:{port}", "--action", "arm_goal"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO)
        out, err = proc.communicate(timeout=60)
        assert proc.returncode == 0, err
        seen = json.loads(out.strip().splitlines()[-1])
        assert seen["project_modules"] == []
        assert seen["accepted"] == {"accepted": True, "reason": ""}
        assert [f["step"] for f in seen["feedback"]] == [1, 2, 3]
        assert seen["feedback"][1] == {"step": 2, "action": [0.5, -1.0], "status": "moving"}
        assert seen["result"] == {"status": 4, "result": {"success": True, "message": "reach", "steps": 3},
                                  "feedback_sent": 3}
        assert 2 in seen["statuses"] and 4 in seen["statuses"]  # EXECUTING, then SUCCEEDED
        assert seen["cancel"] == {"accepted": True}
        assert seen["cancel_result"]["status"] == 5 and seen["cancel_result"]["result"]["success"] is False
        assert seen["garbage_ok"] is False and "did not decode" in seen["garbage"]["error"]
        stats = server.statistics()
        assert stats.decode_errors == 1 and stats.succeeded == 1 and stats.canceled == 1
    finally:
        if proc is not None and proc.poll() is None:
            proc.kill()
            proc.wait(5)
        server_side.close()


def test_a_killed_server_process_ends_the_goal_aborted() -> None:
    """The server's process dies mid-goal: the client's goal ends ABORTED with the reason, in bounded time."""
    from agents_core.transport.goals import GoalStatus  # noqa: PLC0415

    port = free_tcp_port()
    proc = subprocess.Popen([sys.executable, "-m", "tests.agents_zenoh.goal_server", str(port), "doomed"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=REPO)
    client_side = None
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "READY"
        client_side = ZenohTransport(mode="peer", listen=[], connect=[f"tcp/127.0.0.1:{port}"],
                                     multicast_scouting=False)
        feedback: list[dict[str, Any]] = []
        goal = None
        for _ in range(50):
            try:
                goal = client_side.send_goal("doomed", "VisionLanguageAction", {"task": "x"}, feedback=feedback.append,
                                             timeout=2.0)
                break
            except Exception:
                time.sleep(0.1)
        assert goal is not None and goal.accepted
        assert wait_for(lambda: len(feedback) >= 3, timeout=10.0)
        proc.kill()
        proc.wait(10)
        started = time.monotonic()
        status, result = goal.result(15.0)
        assert status == GoalStatus.ABORTED and "went away" in result["message"]
        assert time.monotonic() - started < 15.0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
        if proc.stdout is not None:
            proc.stdout.close()
        if client_side is not None:
            client_side.close()


def test_a_goal_longer_than_one_result_query_still_gets_its_result() -> None:
    """Result queries are answered "pending" after wait_s and asked again; the goal's feedback all arrives."""
    from agents_core.testing.pairs import zenoh_pair  # noqa: PLC0415
    from agents_core.transport.goals import GoalStatus  # noqa: PLC0415

    def slow(handle: GoalHandle) -> dict[str, Any]:
        for step in range(6):
            handle.publish_feedback({"step": step})
            handle.wait_for_cancel(0.3)
        return {"success": True, "steps": 6}

    with zenoh_pair() as (a, b):
        a.create_action_server("slow_goal", "VisionLanguageAction", slow)
        feedback: list[dict[str, Any]] = []
        goal = None
        for _ in range(50):
            try:
                goal = b.send_goal("slow_goal", "VisionLanguageAction", {"task": "x"}, feedback=feedback.append)
                break
            except Exception:
                time.sleep(0.1)
        assert goal is not None
        assert goal.result(15.0) == (GoalStatus.SUCCEEDED, {"success": True, "message": "", "steps": 6})
        assert wait_for(lambda: len(feedback) == 6, timeout=5.0)
