"""A plain rclpy action client (no project module): drives a VisionLanguageAction server.

Run as a script with ``--action NAME`` in the server's ROS domain; prints one JSON line with what
it saw: a goal to completion (feedback, result), a goal cancelled after its first feedback, and
a goal the server rejects (empty task). Imports only rclpy and the interface package.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from typing import Any

import rclpy
from agents_interfaces.action import VisionLanguageAction
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor


def wait(future: Any, timeout: float = 10.0) -> Any:
    deadline = time.monotonic() + timeout
    while not future.done():
        if time.monotonic() > deadline:
            raise TimeoutError("no answer")
        time.sleep(0.01)
    return future.result()


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--action", required=True)
    args = parser.parse_args()
    rclpy.init()
    node = rclpy.create_node("plain_action_client")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.05)

    spinner = threading.Thread(target=spin, daemon=True)
    spinner.start()
    try:
        client = ActionClient(node, VisionLanguageAction, args.action)
        if not client.wait_for_server(timeout_sec=10.0):
            print(json.dumps({"error": "no server"}))
            return 1
        feedback: list[dict[str, Any]] = []
        first = threading.Event()

        def on_feedback(message: Any) -> None:
            fb = message.feedback
            feedback.append({"step": fb.step, "action": list(fb.action), "status": fb.status})
            first.set()

        handle = wait(client.send_goal_async(VisionLanguageAction.Goal(task="reach", max_steps=3),
                                             feedback_callback=on_feedback))
        done = wait(handle.get_result_async())
        done_feedback = list(feedback)

        first.clear()
        long = wait(client.send_goal_async(VisionLanguageAction.Goal(task="hold", max_steps=100000),
                                           feedback_callback=on_feedback))
        first.wait(10.0)
        cancel = wait(long.cancel_goal_async())
        canceled = wait(long.get_result_async())

        rejected = wait(client.send_goal_async(VisionLanguageAction.Goal(task="", max_steps=1)))
        print(json.dumps({
            "accepted": handle.accepted, "feedback": done_feedback,
            "status": done.status, "result": {"success": done.result.success, "message": done.result.message,
                                              "steps": done.result.steps},
            "cancel_goals": len(cancel.goals_canceling), "cancel_status": canceled.status,
            "cancel_success": canceled.result.success, "rejected_accepted": rejected.accepted,
            "project_modules": sorted(m for m in sys.modules if m.startswith(("agents_core", "agents_ros2"))),
        }))
    finally:
        stop.set()
        spinner.join(5.0)
        executor.shutdown(timeout_sec=2.0)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
