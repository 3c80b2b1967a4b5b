"""The VLA recipe (vla_recipe.py) on memory, and in its own process on each cross-process transport (the
``recipe_transport`` fixture: Zenoh, ROS 2): a simulated arm and the goal client in this process, a
gRPC policy server on 127.0.0.1; the arm reaches the pose within its limits, and a cancel mid-goal
stops it with a hold command. On ROS 2 the arm and the client are plain rclpy
(sensor_msgs/JointState, sensor_msgs/Image, an rclpy ActionClient for VisionLanguageAction)."""

from __future__ import annotations

import threading
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("grpc", reason="the vla extra (grpcio) is not installed")

from agents_core.errors import RequestTimeoutError, ServiceUnavailableError
from agents_core.messages import JointStateMsg
from agents_core.testing.helpers import wait_for
from agents_core.testing.pairs import skip_unless_installed
from agents_core.testing.recipes import RecipeTransport, run_recipe
from agents_core.transport.goals import GoalStatus
from tests.components import vla_recipe
from tests.components.sim_arm import SimulatedArm
from tests.servers.policy_server import PolicyTestServer, ReachPolicy

REPO = Path(__file__).resolve().parents[2]
TARGET = {"shoulder": 0.8, "elbow": -0.5}
FAR = {"shoulder": 1.9, "elbow": 0.9}


def check_reach(commands: list[list[float]], final: dict[str, float]) -> None:
    """The arm ended at the target (the elbow at its limit) and no command broke a limit."""
    assert final["shoulder"] == pytest.approx(TARGET["shoulder"], abs=1e-6)
    assert final["elbow"] == pytest.approx(vla_recipe.ELBOW_LOWER, abs=1e-6)
    previous = [0.0, 0.0]
    for shoulder, elbow in commands:
        assert elbow >= vla_recipe.ELBOW_LOWER - 1e-9
        step = vla_recipe.VELOCITY_LIMIT / vla_recipe.RATE + 1e-9
        assert abs(shoulder - previous[0]) <= step and abs(elbow - previous[1]) <= step
        previous = [shoulder, elbow]


def check_hold(hold: list[float], last_moves: list[list[float]], before: dict[str, float],
               after: dict[str, float]) -> None:
    """The last command after the cancel held the arm where it was, and nothing moved it afterwards."""
    assert any(np.allclose(hold, move) for move in last_moves), (hold, last_moves)
    assert after == before
    assert 0 < after["shoulder"] < FAR["shoulder"]


def _ask_through_the_framework(recipe_transport: RecipeTransport, server: PolicyTestServer) -> None:
    user = recipe_transport.open_asker()
    arm = SimulatedArm(user, {"shoulder": 0.0, "elbow": 0.0}, state_topic=vla_recipe.STATE,
                       command_topic=vla_recipe.COMMANDS, camera_topic=vla_recipe.CAMERA)
    try:
        feedback: list[dict[str, Any]] = []

        def send(max_steps: int) -> Any:
            deadline = time.monotonic() + 15
            while True:
                try:
                    return user.send_goal("arm_vla", "VisionLanguageAction", {"task": "reach", "max_steps":
                                                                               max_steps},
                                          feedback=feedback.append, timeout=5.0)
                except (ServiceUnavailableError, RequestTimeoutError):
                    if time.monotonic() > deadline:
                        raise
                    time.sleep(0.2)

        time.sleep(0.5)  # the recipe sees the arm's state before the goal's first observation
        status, result = send(80).result(timeout=30)
        assert status == GoalStatus.SUCCEEDED, result
        assert result["steps"] == 80
        commands = [c.position.tolist() for c in arm.commands if isinstance(c, JointStateMsg)]
        check_reach(commands, arm.snapshot())
        assert wait_for(lambda: len(feedback) == 80, 5.0)

        server.policy = ReachPolicy(FAR, step=0.01)
        feedback.clear()
        goal = send(100_000)
        assert wait_for(lambda: len(feedback) >= 10, 15.0)
        assert goal.cancel(timeout=5.0)
        status, result = goal.result(timeout=15)
        assert status == GoalStatus.CANCELED and result["message"] == "canceled"
        time.sleep(0.2)  # the hold command travels
        before = arm.snapshot()
        time.sleep(0.3)
        moves = [c.position.tolist() for c in arm.commands if isinstance(c, JointStateMsg)]
        check_hold(moves[-1], moves[-4:-1], before, arm.snapshot())
    finally:
        arm.close()


#: How a user of each transport drives the recipe; the framework's own transport where none is named.
USER_SIDE: dict[str, Callable[[RecipeTransport, PolicyTestServer], None]] = {
    "ros2": lambda _, server: _plain_rclpy_side(server)}


def test_recipe_in_its_own_process(recipe_transport: RecipeTransport, tmp_path: Path) -> None:
    if recipe_transport.name == "ros2":
        skip_unless_installed("ros2", "agents_interfaces")
    with PolicyTestServer(ReachPolicy(TARGET, step=0.05)) as server, \
            run_recipe("tests.components.vla_recipe", recipe_transport, tmp_path, ["--policy-port", str(server.port)],
                       cwd=REPO):
        USER_SIDE.get(recipe_transport.name, _ask_through_the_framework)(recipe_transport, server)


class _PlainArm:
    """The simulated arm as a plain rclpy node: follows sensor_msgs/JointState position commands."""

    def __init__(self, node: Any, joint_state: Any, image: Any) -> None:
        self.positions = {"shoulder": 0.0, "elbow": 0.0}
        self.commands: list[list[float]] = []
        self._lock = threading.Lock()
        self._msg, self._image = joint_state, image
        self._state = node.create_publisher(joint_state, "/joint_states", 10)
        self._camera = node.create_publisher(image, "/camera", 10)
        node.create_subscription(joint_state, "/joint_commands", self._on_command, 10)
        node.create_timer(0.01, self._publish_state)
        node.create_timer(0.1, self._publish_image)

    def _on_command(self, msg: Any) -> None:
        with self._lock:
            for name, position in zip(msg.name, msg.position, strict=True):
                self.positions[name] = float(position)
            self.commands.append([self.positions["shoulder"], self.positions["elbow"]])

    def _publish_state(self) -> None:
        with self._lock:
            msg = self._msg(name=list(self.positions), position=list(self.positions.values()))
        self._state.publish(msg)

    def _publish_image(self) -> None:
        msg = self._image(height=16, width=16, encoding="rgb8", is_bigendian=0, step=48)
        msg.data = bytes(16 * 16 * 3)
        self._camera.publish(msg)

    def snapshot(self) -> dict[str, float]:
        with self._lock:
            return dict(self.positions)


def _wait(future: Any, timeout: float = 15.0) -> Any:
    assert wait_for(future.done, timeout), "no answer from the action server"
    return future.result()


def _plain_rclpy_side(server: PolicyTestServer) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # rosidl's parser imports lark -> sre_parse
        import rclpy  # noqa: PLC0415
        import rosidl_generator_py  # noqa: F401, PLC0415
        from agents_interfaces.action import VisionLanguageAction  # noqa: PLC0415
        from rclpy.action import ActionClient  # noqa: PLC0415
        from rclpy.executors import SingleThreadedExecutor  # noqa: PLC0415
        from sensor_msgs.msg import Image, JointState  # noqa: PLC0415

    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("plain_arm", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    arm = _PlainArm(node, JointState, Image)
    client = ActionClient(node, VisionLanguageAction, "/arm_vla")
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    feedback: list[Any] = []
    on_feedback: Callable[[Any], None] = lambda message: feedback.append(message.feedback)  # noqa: E731
    try:
        assert client.wait_for_server(timeout_sec=15.0)
        time.sleep(0.5)  # the recipe sees the arm's state before the goal's first observation
        handle = _wait(client.send_goal_async(VisionLanguageAction.Goal(task="reach", max_steps=80),
                                              feedback_callback=on_feedback))
        assert handle.accepted
        done = _wait(handle.get_result_async(), 30.0)
        assert done.status == GoalStatus.SUCCEEDED, done.result.message
        assert done.result.success and done.result.steps == 80
        check_reach(list(arm.commands), arm.snapshot())
        assert wait_for(lambda: len(feedback) == 80, 5.0)
        assert feedback[-1].step == 80 and len(feedback[-1].action) == 2

        server.policy = ReachPolicy(FAR, step=0.01)
        feedback.clear()
        long = _wait(client.send_goal_async(VisionLanguageAction.Goal(task="reach far", max_steps=100_000),
                                            feedback_callback=on_feedback))
        assert wait_for(lambda: len(feedback) >= 10, 15.0)
        cancel = _wait(long.cancel_goal_async())
        assert len(cancel.goals_canceling) == 1
        canceled = _wait(long.get_result_async())
        assert canceled.status == GoalStatus.CANCELED and not canceled.result.success
        time.sleep(0.2)  # the hold command travels
        before = arm.snapshot()
        time.sleep(0.3)
        check_hold(arm.commands[-1], arm.commands[-4:-1], before, arm.snapshot())
    finally:
        executor.shutdown()
        spinner.join(timeout=5)
        client.destroy()
        node.destroy_node()
        rclpy.shutdown(context=context)


def test_recipe_on_memory() -> None:
    from agents_core import Launcher  # noqa: PLC0415

    with PolicyTestServer(ReachPolicy(TARGET, step=0.05)) as server:
        launcher = Launcher("memory")
        launcher.add_pkg(components=[vla_recipe.build(server.port)])
        with launcher:
            arm = SimulatedArm(launcher.transport, {"shoulder": 0.0, "elbow": 0.0}, state_topic=vla_recipe.STATE,
                               command_topic=vla_recipe.COMMANDS, camera_topic=vla_recipe.CAMERA)
            try:
                time.sleep(0.3)
                status, result = launcher.transport.send_goal(
                    "arm_vla", "VisionLanguageAction", {"task": "reach", "max_steps": 80}).result(timeout=30)
                assert status == GoalStatus.SUCCEEDED, result
                check_reach([c.position.tolist() for c in arm.commands if isinstance(c, JointStateMsg)],
                            arm.snapshot())
                server.policy = ReachPolicy(FAR, step=0.01)
                feedback: list[dict[str, Any]] = []
                goal = launcher.transport.send_goal("arm_vla", "VisionLanguageAction",
                                                    {"task": "reach far", "max_steps": 100_000},
                                                    feedback=feedback.append)
                assert wait_for(lambda: len(feedback) >= 10, 15.0)
                assert goal.cancel(timeout=5.0)
                assert goal.result(timeout=15)[0] == GoalStatus.CANCELED
                before = arm.snapshot()
                time.sleep(0.3)
                moves = [c.position.tolist() for c in arm.commands if isinstance(c, JointStateMsg)]
                check_hold(moves[-1], moves[-4:-1], before, arm.snapshot())
            finally:
                arm.close()
