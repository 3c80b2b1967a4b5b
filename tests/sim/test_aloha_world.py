"""gym-aloha's transfer-cube as a world: 14 joints on ``joint_states``, the ``top`` camera as an Image, 14 joint
targets in on ``action`` (as a Float64 array and as a JointState), the task's own success rule.

Needs the ``aloha`` extra (gym-aloha, with dm-control): ``nox -s sim_aloha`` installs it and runs this module
before the scripted expert's evaluation; elsewhere it skips, saying so. A step costs ~0.4 s (meshes and 10 physics
substeps), so the episodes here are a few steps long.
"""

from __future__ import annotations

import importlib.util
import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core import Launcher, Topic
from agents_core.messages import ImageMsg, JointStateMsg
from agents_core.sim import GymWorld, GymWorldConfig
from agents_core.testing.helpers import wait_for

pytestmark = [pytest.mark.slow, pytest.mark.skipif(
    importlib.util.find_spec("gym_aloha") is None,
    reason="gym-aloha not installed: pip install 'agents-core[sim,aloha]' (nox -s sim_aloha)")]

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "examples"))
from evaluate_aloha import AlohaExpert, aloha_world  # noqa: E402

STEPS = 3
#: gym-aloha's joint order (agent_pos): each arm's six joints, then its gripper; left arm first.
JOINTS = [f"{side}_{joint}" for side in ("left", "right")
          for joint in ("waist", "shoulder", "elbow", "forearm_roll", "wrist_angle", "wrist_rotate", "gripper")]


def _episode(launcher: Launcher, world: str = "world", **kwargs: Any) -> dict[str, Any]:
    reply = launcher.transport.request(f"{world}/execute_method", {"method": "run_episode", "kwargs": kwargs,
                                                                   "timeout": 300}, timeout=310)
    result: dict[str, Any] = reply["result"]
    return result


def _started(*components: Any) -> Launcher:
    launcher = Launcher(transport="memory", quiet=True)
    launcher.add_pkg(components=list(components))
    launcher.start()
    assert wait_for(launcher.all_active, timeout=120)
    return launcher


def test_transfer_cube_publishes_14_joints_and_the_top_camera() -> None:
    heard: dict[str, list[Any]] = {}
    lock = threading.Lock()
    launcher = _started(aloha_world(), AlohaExpert())
    subs = []
    try:
        for name, kind in [("top", "Image"), ("joint_states", "JointState"), ("observation", "Float64MultiArray"),
                           ("reward", "Float64"), ("action", "Float64MultiArray")]:
            def got(value: Any, name: str = name) -> None:
                with lock:
                    heard.setdefault(name, []).append(value)
            subs.append(launcher.transport.create_subscription(Topic(name, kind), got))
        result = _episode(launcher, seed=0, max_steps=STEPS)
        assert wait_for(lambda: len(heard.get("reward", [])) == STEPS, timeout=10), (result["ended"], result["reason"])
    finally:
        for sub in subs:
            sub.close()
        launcher.stop()
    assert (result["ended"], result["steps"], result["success"]) == ("step_limit", STEPS, False)
    assert heard["reward"] == pytest.approx(result["rewards"])
    assert len(heard["top"]) == len(heard["joint_states"]) == STEPS + 1  # the reset's and each step's
    frame = heard["top"][0]
    assert isinstance(frame, ImageMsg) and frame.encoding == "rgb8" and frame.data.shape == (480, 640, 3)
    assert frame.data.std() > 1.0  # a rendered scene, not a blank frame (gym-aloha renders at 640x480, always)
    joints = heard["joint_states"][0]
    assert isinstance(joints, JointStateMsg) and len(joints.name) == len(joints.position) == 14
    # The observation: agent_pos (the same 14 joint positions), then the simulation time and the cube's pose.
    observation = heard["observation"][0]
    assert observation.shape == (14 + 1 + 7,)
    np.testing.assert_allclose(observation[:14], joints.position)
    assert observation[14] == pytest.approx(0.0) and 0.0 < observation[17] < 0.2  # the cube on the table
    assert [a.shape for a in heard["action"]] == [(14,)] * len(heard["action"]) and len(heard["action"]) >= STEPS


def test_transfer_cube_takes_a_joint_state_action_by_name_and_renders_at_the_world_s_size() -> None:
    from agents_core.components import Component  # noqa: PLC0415

    class HoldStill(Component):
        """Answers each observation with the joint positions it reads, as a JointState (names in its own order)."""

        def __init__(self) -> None:
            observation = Topic("observation", "Float64MultiArray")
            super().__init__(inputs=[observation], outputs=[Topic("action", "JointState")], trigger=observation,
                             component_name="hold_still")

        def _execution_step(self, **kwargs: Any) -> None:
            observation = self.trig_callbacks["observation"].get_output()
            if observation is not None:  # names reversed: the world must put them back in its order
                order = list(range(13, -1, -1))
                self.publishers_dict["action"].publish(JointStateMsg(
                    name=[JOINTS[i] for i in order], position=[float(observation[i]) for i in order]))

    world = GymWorld("gym_aloha/AlohaTransferCube-v0", action_type="JointState", joint_names=JOINTS,
                     env_kwargs={"obs_type": "pixels_agent_pos"},
                     cameras={"front": "render"},
                     config=GymWorldConfig(step_timeout=60.0, action_timeout=60.0, render_width=80, render_height=60))
    heard: list[JointStateMsg] = []
    frames: list[ImageMsg] = []
    launcher = _started(world, HoldStill())
    subs = [launcher.transport.create_subscription(Topic("joint_states", "JointState"), heard.append),
            launcher.transport.create_subscription(Topic("front", "Image"), frames.append)]
    try:
        result = _episode(launcher, seed=1, max_steps=STEPS)
        assert wait_for(lambda: len(heard) == len(frames) == STEPS + 1, timeout=10), (result, len(heard))
    finally:
        for sub in subs:
            sub.close()
        launcher.stop()
    # render() at the world's render size (gym-aloha's visualization_width / _height).
    assert frames[0].data.shape == (60, 80, 3) and frames[0].data.std() > 1.0
    assert (result["ended"], result["steps"]) == ("step_limit", STEPS), result["reason"]
    assert heard[0].name == JOINTS
    # Held where they started: the arms' joints stay close to their first positions (the grippers may settle).
    arms = [i for i, name in enumerate(JOINTS) if not name.endswith("gripper")]
    drift = np.abs(np.asarray(heard[-1].position)[arms] - np.asarray(heard[0].position)[arms]).max()
    assert drift < 0.05, drift
