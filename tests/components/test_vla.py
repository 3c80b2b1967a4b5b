"""The VLA component on the memory transport: a simulated arm, a real gRPC policy server, goals sent
through the transport's goal API; the recipe (reach, limits, cancel -> hold) and every bad input."""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("grpc", reason="the vla extra (grpcio) is not installed")

from agents_core.clients.lerobot import LeRobotClient
from agents_core.components import VLA
from agents_core.config import VLAConfig
from agents_core.errors import ConfigError, WiringError
from agents_core.events import Event
from agents_core.launch.launcher import Launcher
from agents_core.messages import JointJogMsg, JointStateMsg, JointTrajectoryMsg
from agents_core.models import LeRobotPolicy
from agents_core.status import HealthStatus
from agents_core.testing.helpers import free_tcp_port, wait_for
from agents_core.topics import Topic
from agents_core.transport.goals import GoalStatus
from tests.components.sim_arm import SimulatedArm
from tests.servers.policy_server import PolicyTestServer, ReachPolicy

JOINTS = ["shoulder", "elbow"]
TARGET = {"shoulder": 0.8, "elbow": -0.5}
ELBOW_LOWER = -0.3
VELOCITY_LIMIT = 2.0
RATE = 50.0

STATE = Topic(name="joint_states", msg_type="JointState")
CAMERA = Topic(name="camera", msg_type="Image")


def policy_model(actions: list[str] | None = None) -> LeRobotPolicy:
    names = actions or JOINTS
    return LeRobotPolicy(
        name="arm_policy", policy_type="act", actions_per_chunk=10, policy_device="cpu",
        features={"observation.state": {"dtype": "float32", "shape": [2], "names": JOINTS},
                  "observation.images.front": {"dtype": "image", "shape": [16, 16, 3],
                                               "names": ["height", "width", "channels"]}},
        actions={"action": {"dtype": "float32", "shape": [len(names)], "names": names}})


def vla_config(**overrides: Any) -> VLAConfig:
    settings: dict[str, Any] = dict(
        joint_names_map={n: n for n in JOINTS}, camera_inputs_map={"front": CAMERA.name},
        observation_sending_rate=20.0, action_sending_rate=RATE, max_timesteps=60, state_timeout=0.5,
        action_wait_timeout=3.0,
        joint_limits={"elbow": {"lower": ELBOW_LOWER, "upper": 1.0, "velocity": VELOCITY_LIMIT},
                      "shoulder": {"lower": -2.0, "upper": 2.0, "velocity": VELOCITY_LIMIT}})
    settings.update(overrides)
    return VLAConfig(**settings)


class Rig:
    """A launched VLA, its simulated arm, and the transport to send goals on."""

    def __init__(self, vla: VLA, launcher: Launcher, arm: SimulatedArm) -> None:
        self.vla, self.launcher, self.arm = vla, launcher, arm
        self.feedback: list[dict[str, Any]] = []

    def send(self, task: str = "reach the pose", max_steps: int = 0, timeout: float = 5.0) -> Any:
        return self.launcher.transport.send_goal(self.vla.action_name, "VisionLanguageAction",
                                                 {"task": task, "max_steps": max_steps},
                                                 feedback=self.feedback.append, timeout=timeout)


@contextmanager
def rig(port: int, *, output: Topic | None = None, config: VLAConfig | None = None,
        model: LeRobotPolicy | None = None, start_positions: dict[str, float] | None = None,
        inference_timeout: float = 2) -> Iterator[Rig]:
    command = output or Topic(name="joint_commands", msg_type="JointState")
    client = LeRobotClient(model or policy_model(), port=port, allow_pickle=True, inference_timeout=inference_timeout)
    vla = VLA(inputs=[STATE, CAMERA], outputs=[command], model_client=client, config=config or vla_config(),
              trigger=None, component_name="arm_vla")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[vla])
    launcher.start()
    arm = SimulatedArm(launcher.transport, dict(start_positions or dict.fromkeys(JOINTS, 0.0)), state_topic=STATE,
                       command_topic=command, camera_topic=CAMERA)
    try:
        assert wait_for(lambda: vla.callbacks[STATE.name].got_msg and vla.callbacks[CAMERA.name].got_msg, 5.0)
        yield Rig(vla, launcher, arm)
    finally:
        arm.close()
        launcher.stop()


@pytest.fixture
def server() -> Iterator[PolicyTestServer]:
    with PolicyTestServer(ReachPolicy(TARGET, step=0.05)) as s:
        yield s


def positions_of(cmd: JointStateMsg) -> dict[str, float]:
    return dict(zip(cmd.name, cmd.position.tolist(), strict=True))


class TestRecipe:
    def test_the_arm_reaches_the_pose_within_its_limits(self, server: PolicyTestServer) -> None:
        with rig(server.port) as r:
            goal = r.send(max_steps=80)
            assert goal.accepted
            status, result = goal.result(timeout=20)
            # The result can arrive before the arm's subscription has delivered the last command.
            wait_for(lambda: sum(isinstance(c, JointStateMsg) for c in r.arm.commands) >= 80, timeout=5.0)
            commands = [c for c in r.arm.commands if isinstance(c, JointStateMsg)]
            final = r.arm.snapshot()
        assert status == GoalStatus.SUCCEEDED, result
        assert result == {"success": True, "message": "80 steps done", "steps": 80}
        assert final["shoulder"] == pytest.approx(TARGET["shoulder"], abs=1e-6)
        assert final["elbow"] == pytest.approx(ELBOW_LOWER)  # the policy asked for -0.5: clipped at the limit
        assert len(commands) == 80
        previous = dict.fromkeys(JOINTS, 0.0)
        for cmd in commands:
            pos = positions_of(cmd)
            assert pos["elbow"] >= ELBOW_LOWER - 1e-9
            for joint in JOINTS:  # never faster than the velocity limit allows in one control period
                assert abs(pos[joint] - previous[joint]) <= VELOCITY_LIMIT / RATE + 1e-9
            previous = pos
        assert [f["step"] for f in r.feedback] == list(range(1, 81))
        assert r.feedback[-1]["action"] == pytest.approx([final["shoulder"], final["elbow"]])
        # What the policy saw: the task, the camera and the arm's state by the policy's names.
        obs = server.observations[0].observation
        assert obs["task"] == "reach the pose" and obs["front"].shape == (16, 16, 3)
        assert set(obs) == {"shoulder", "elbow", "front", "task"}
        assert r.vla.health_status == HealthStatus.HEALTHY

    def test_cancel_mid_goal_stops_the_arm_with_a_hold_command(self) -> None:
        with PolicyTestServer(ReachPolicy({"shoulder": 1.9, "elbow": 0.9}, step=0.01)) as slow, rig(slow.port) as r:
            goal = r.send(max_steps=10_000)
            assert wait_for(lambda: len(r.feedback) >= 10, 10.0)
            assert goal.cancel(timeout=5.0)
            status, result = goal.result(timeout=10)
            hold = r.arm.commands[-1]
            at_hold = r.arm.snapshot()
            time.sleep(0.3)
            after = r.arm.snapshot()
            holds = r.vla.holds_sent
        assert status == GoalStatus.CANCELED and result["success"] is False and result["message"] == "canceled"
        assert 0 < at_hold["shoulder"] < 1.9  # stopped on the way
        assert holds == 1
        assert isinstance(hold, JointStateMsg)
        assert positions_of(hold) == pytest.approx(at_hold, abs=1e-9)
        assert after == at_hold  # nothing moves it after the hold

    @pytest.mark.parametrize("output_type, msg_class", [("JointTrajectory", JointTrajectoryMsg),
                                                        ("JointJog", JointJogMsg)])
    def test_trajectory_and_jog_outputs_reach_the_pose(self, server: PolicyTestServer, output_type: str,
                                                       msg_class: type) -> None:
        with rig(server.port, output=Topic(name="arm_cmd", msg_type=output_type)) as r:
            status, result = r.send(max_steps=60).result(timeout=20)
            final = r.arm.snapshot()
            kinds = {type(c) for c in r.arm.commands}
        assert status == GoalStatus.SUCCEEDED, result
        assert kinds == {msg_class}
        assert final["shoulder"] == pytest.approx(0.8, abs=0.05)
        assert final["elbow"] == pytest.approx(ELBOW_LOWER, abs=0.05)

    def test_velocity_commands_are_clipped_to_the_velocity_limit(self) -> None:
        def fast(obs: Any, setup: Any) -> np.ndarray:
            return np.tile([5.0, -5.0], (setup.actions_per_chunk, 1)).astype(np.float32)

        with PolicyTestServer(fast) as s, rig(s.port, config=vla_config(action_output_type="velocities")) as r:
            status, _ = r.send(max_steps=5).result(timeout=10)
            commands = [c for c in r.arm.commands if isinstance(c, JointStateMsg)]
        assert status == GoalStatus.SUCCEEDED
        assert all(c.velocity.tolist() == [VELOCITY_LIMIT, -VELOCITY_LIMIT] for c in commands[:5])

    def test_the_termination_event_ends_the_goal_successfully(self, server: PolicyTestServer) -> None:
        stop = Event("arm_done")
        with rig(server.port) as r:
            r.vla.set_termination_trigger("event", stop_event=stop)
            goal = r.send(max_steps=10_000)
            assert wait_for(lambda: len(r.feedback) >= 5, 10.0)
            stop.trigger()
            status, result = goal.result(timeout=10)
        assert status == GoalStatus.SUCCEEDED and result["message"] == "the termination event fired"
        assert 5 <= result["steps"] < 10_000


class TestBadInput:
    def check_abort(self, r: Rig, goal: Any, reason: str, health: HealthStatus) -> None:
        status, result = goal.result(timeout=20)
        assert status == GoalStatus.ABORTED, result
        assert result["success"] is False and reason in result["message"]
        assert r.vla.holds_sent >= 1
        assert r.vla.health_status == health

    def check_next_goal_works(self, r: Rig) -> None:
        status, result = r.send(max_steps=5).result(timeout=20)
        assert status == GoalStatus.SUCCEEDED, result
        assert r.vla.health_status == HealthStatus.HEALTHY

    @pytest.mark.parametrize("fault, reason", [("nan", "non-finite"), ("wrong_dim", "dimension 3; expected 2")])
    def test_a_bad_policy_answer_aborts_and_the_next_goal_works(self, server: PolicyTestServer, fault: str,
                                                                reason: str) -> None:
        with rig(server.port) as r:
            server.fault = fault
            goal = r.send(max_steps=20)
            self.check_abort(r, goal, reason, HealthStatus.ALGORITHM_FAILURE)
            assert not any(isinstance(c, JointStateMsg) and len(c.position) and
                           not np.isfinite(c.position).all() for c in r.arm.commands)
            server.fault = None
            self.check_next_goal_works(r)

    def test_joints_missing_from_the_state_abort(self, server: PolicyTestServer) -> None:
        with rig(server.port) as r:
            r.arm.hide_joints = {"elbow"}
            time.sleep(0.1)
            self.check_abort(r, r.send(max_steps=20), "['elbow'] missing from the state", HealthStatus.SYSTEM_FAILURE)
            r.arm.hide_joints = set()
            time.sleep(0.1)
            self.check_next_goal_works(r)

    def test_a_stale_joint_state_aborts(self, server: PolicyTestServer) -> None:
        with rig(server.port) as r:
            goal = r.send(max_steps=100_000)
            assert wait_for(lambda: len(r.feedback) >= 3, 10.0)
            r.arm.publish_state = False
            self.check_abort(r, goal, "is stale", HealthStatus.SYSTEM_FAILURE)
            r.arm.publish_state = True
            time.sleep(0.1)
            self.check_next_goal_works(r)

    def test_a_policy_server_that_dies_mid_goal(self) -> None:
        port = free_tcp_port()
        script = Path(__file__).resolve().parents[1] / "servers" / "policy_server.py"
        command = [sys.executable, str(script), "--port", str(port), "--target", '{"shoulder": 1.9}', "--step", "0.005"]

        @contextmanager
        def server_process() -> Iterator[subprocess.Popen[str]]:
            with subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True) as proc:
                try:
                    assert proc.stdout is not None and "listening" in proc.stdout.readline()
                    yield proc
                finally:
                    if proc.poll() is None:
                        proc.kill()
                    proc.wait(timeout=10)

        with server_process() as proc, rig(port) as r:
            goal = r.send(max_steps=100_000)
            assert wait_for(lambda: len(r.feedback) >= 5, 10.0)
            proc.kill()  # by PID, mid-goal
            proc.wait(timeout=10)
            self.check_abort(r, goal, "policy server failed", HealthStatus.COMPONENT_FAILURE)
            with server_process():  # a restarted server: the client sends the policy again
                self.check_next_goal_works(r)

    def test_a_second_goal_is_rejected_by_default(self, server: PolicyTestServer) -> None:
        with rig(server.port) as r:
            first = r.send(max_steps=100_000)
            assert wait_for(lambda: len(r.feedback) >= 2, 10.0)
            second = r.send(max_steps=5)
            assert first.accepted and not second.accepted
            assert second.status == GoalStatus.REJECTED
            assert first.cancel(timeout=5.0)
            assert first.result(timeout=10)[0] == GoalStatus.CANCELED

    def test_a_second_goal_preempts_when_configured(self, server: PolicyTestServer) -> None:
        with rig(server.port, config=vla_config(on_new_goal="preempt")) as r:
            first = r.send(max_steps=100_000)
            assert wait_for(lambda: len(r.feedback) >= 2, 10.0)
            second = r.send(task="another task", max_steps=5)
            assert second.accepted
            assert first.result(timeout=10)[0] == GoalStatus.CANCELED
            status, result = second.result(timeout=20)
            holds = r.vla.holds_sent
        assert status == GoalStatus.SUCCEEDED and result["steps"] == 5
        assert holds == 1
        assert server.observations[-1].observation["task"] == "another task"

    def test_a_policy_commanding_an_unknown_joint_never_starts(self, server: PolicyTestServer) -> None:
        client = LeRobotClient(policy_model(actions=["shoulder", "gripper"]), port=server.port, allow_pickle=True)
        vla = VLA(inputs=[STATE, CAMERA], outputs=[Topic(name="cmd", msg_type="JointState")], model_client=client,
                  config=vla_config(), trigger=None, component_name="arm_vla")
        launcher = Launcher("memory")
        launcher.add_pkg(components=[vla])
        with pytest.raises(ConfigError, match=r"\['gripper'\]"):
            launcher.start()
        launcher.stop()

    def test_wiring_errors(self, server: PolicyTestServer) -> None:
        client = LeRobotClient(policy_model(), port=server.port, allow_pickle=True)
        with pytest.raises(WiringError, match="trigger must be None"):
            VLA(inputs=[STATE], outputs=[Topic(name="c", msg_type="JointState")], model_client=client,
                config=vla_config(camera_inputs_map={}), trigger=1.0)  # type: ignore[arg-type]
        with pytest.raises(WiringError, match="not one of its Image"):
            VLA(inputs=[STATE], outputs=[Topic(name="c", msg_type="JointState")], model_client=client,
                config=vla_config())
        with pytest.raises(ConfigError, match="joint_names_map is empty"):
            VLA(inputs=[STATE], outputs=[Topic(name="c", msg_type="JointState")], model_client=client,
                config=vla_config(joint_names_map={}, camera_inputs_map={}))
        with pytest.raises(ConfigError, match="on_new_goal"):
            vla_config(on_new_goal="queue")

    def test_urdf_limits_clip_commands(self, server: PolicyTestServer, tmp_path: Path) -> None:
        urdf = tmp_path / "arm.urdf"
        urdf.write_text("""<robot name="arm">
  <joint name="shoulder" type="revolute"><limit lower="-1" upper="0.5" velocity="5"/></joint>
  <joint name="elbow" type="continuous"><limit velocity="5"/></joint>
</robot>""", encoding="utf-8")
        with rig(server.port, config=vla_config(joint_limits=None, robot_urdf_file=str(urdf))) as r:
            status, _ = r.send(max_steps=40).result(timeout=20)
            final = r.arm.snapshot()
        assert status == GoalStatus.SUCCEEDED
        assert final["shoulder"] == pytest.approx(0.5) and final["elbow"] == pytest.approx(-0.5, abs=1e-6)


def test_the_readme_example_builds_and_reads_its_urdf(server: PolicyTestServer, tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    import re  # noqa: PLC0415

    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text(encoding="utf-8")
    block = next(b for b in re.findall(r"```python\n(.*?)```", readme, flags=re.S) if "VLAConfig(" in b)
    build = block.split("# then, from any process")[0].replace("port=8080", f"port={server.port}")
    (tmp_path / "info.json").write_text('{"features": {"observation.state": {"dtype": "float32", "shape": [2], '
                                        '"names": ["shoulder_pan.pos", "gripper.pos"]}, "action": {"dtype": '
                                        '"float32", "shape": [2], "names": ["shoulder_pan.pos", "gripper.pos"]}}}')
    (tmp_path / "so100.urdf").write_text('<robot name="so100"><joint name="shoulder_pan" type="revolute">'
                                         '<limit lower="-2" upper="2" velocity="3"/></joint><joint name="gripper" '
                                         'type="prismatic"><limit lower="0" upper="0.04" velocity="0.1"/></joint>'
                                         '</robot>')
    monkeypatch.chdir(tmp_path)
    namespace: dict[str, Any] = {"Topic": Topic}
    exec(compile(build, "README.md", "exec"), namespace)
    vla = namespace["vla"]
    launcher = Launcher("memory")
    launcher.add_pkg(components=[vla])
    with launcher:
        assert vla._limits["gripper"].upper == pytest.approx(0.04)
        assert vla._action_names == ["shoulder_pan.pos", "gripper.pos"]


def test_deactivating_mid_goal_ends_it_with_a_hold(server: PolicyTestServer) -> None:
    with rig(server.port) as r:
        goal = r.send(max_steps=100_000)
        assert wait_for(lambda: len(r.feedback) >= 3, 10.0)
        r.vla.deactivate()
        status, result = goal.result(timeout=10)
        # The runtime closes the action server first: a running goal ends ABORTED with that reason.
        assert status == GoalStatus.ABORTED and "closed" in result["message"], result
        assert wait_for(lambda: r.vla.holds_sent == 1, 5.0)
        hold = r.arm.commands[-1]
        assert isinstance(hold, JointStateMsg)
        assert positions_of(hold) == pytest.approx(r.arm.snapshot(), abs=1e-9)
        assert isinstance(r.arm.commands[-1], JointStateMsg)


def test_a_hanging_policy_server_aborts_the_goal_after_the_inference_timeout() -> None:
    with PolicyTestServer(fault="hang") as hanging, rig(hanging.port) as r:
        status, result = r.send(max_steps=10).result(timeout=20)
        assert status == GoalStatus.ABORTED and "policy server failed" in result["message"], result
        assert "no action chunk within" in result["message"] or "timed out" in result["message"]
        assert r.vla.health_status == HealthStatus.COMPONENT_FAILURE and r.vla.holds_sent == 1


def test_a_chunk_for_a_future_step_is_refused() -> None:
    from agents_core.clients.lerobot import protocol as wire  # noqa: PLC0415

    ahead = wire.dumps_payload([wire.TimedAction(0.0, 10_000 + i, np.zeros(2)) for i in range(3)])
    with PolicyTestServer(actions_payload=ahead) as server, rig(server.port) as r:
        status, result = r.send(max_steps=10).result(timeout=20)
        assert status == GoalStatus.ABORTED and "with actions from step 10000" in result["message"], result
        assert r.vla.health_status == HealthStatus.ALGORITHM_FAILURE
        assert not any(isinstance(c, JointStateMsg) and len(c.position) and c.position.any() for c in r.arm.commands)


def test_no_action_for_the_wait_timeout_aborts_without_waiting_for_the_inference_timeout() -> None:
    with PolicyTestServer(fault="hang") as hanging, \
            rig(hanging.port, config=vla_config(action_wait_timeout=0.5), inference_timeout=30) as r:
        start = time.monotonic()
        status, result = r.send(max_steps=10).result(timeout=20)
        took = time.monotonic() - start
        assert status == GoalStatus.ABORTED and "no action from the policy for 0.5 s" in result["message"], result
        assert took < 10.0  # far below the client's 30 s inference timeout
        assert r.vla.holds_sent == 1
