"""GymWorld's topics, actions and clocks, on the memory transport with Gymnasium's Reacher-v5."""

from __future__ import annotations

import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core import Launcher, Topic
from agents_core.errors import AlgorithmFailure, ConfigError
from agents_core.messages import ImageMsg, JointStateMsg, TwistMsg
from agents_core.sim import GymWorld, GymWorldConfig, reacher_success
from agents_core.sim.convert import action_vector
from agents_core.testing.helpers import wait_for

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "examples"))
from evaluate_reacher import ReacherExpert


def _episode(launcher: Launcher, **kwargs: Any) -> dict[str, Any]:
    reply = launcher.transport.request("world/execute_method", {"method": "run_episode", "kwargs": kwargs,
                                                                "timeout": 60}, timeout=70)
    result: dict[str, Any] = reply["result"]
    return result


def _started(*components: Any) -> Launcher:
    launcher = Launcher(transport="memory", quiet=True)
    launcher.add_pkg(components=list(components))
    launcher.start()
    assert wait_for(launcher.all_active, timeout=30)
    return launcher


def test_each_step_publishes_camera_joints_reward_and_observation() -> None:
    heard: dict[str, list[Any]] = {}
    lock = threading.Lock()
    launcher = _started(GymWorld("Reacher-v5", success=reacher_success()), ReacherExpert())
    subs = []
    try:
        for name, kind in [("camera", "Image"), ("joint_states", "JointState"), ("reward", "Float64"),
                           ("terminated", "Bool"), ("truncated", "Bool"), ("observation", "Float64MultiArray")]:
            def got(value: Any, name: str = name) -> None:
                with lock:
                    heard.setdefault(name, []).append(value)
            subs.append(launcher.transport.create_subscription(Topic(name, kind), got))
        result = _episode(launcher, seed=5, max_steps=10)
        assert wait_for(lambda: len(heard.get("reward", [])) == 10, timeout=5)
    finally:
        for sub in subs:
            sub.close()
        launcher.stop()
    assert result["steps"] == 10 and result["ended"] == "step_limit"
    assert len(heard["camera"]) == 11 and len(heard["joint_states"]) == 11  # the reset's and each step's
    assert len(heard["observation"]) == 10  # not the last one: no agent answers an episode's end
    frame = heard["camera"][0]
    assert isinstance(frame, ImageMsg) and frame.data.shape == (120, 160, 3) and frame.encoding == "rgb8"
    joints = heard["joint_states"][-1]
    assert isinstance(joints, JointStateMsg) and joints.name == ["joint0", "joint1", "target_x", "target_y"]
    assert len(joints.velocity) == 4
    assert heard["reward"] == pytest.approx(result["rewards"])
    assert heard["truncated"] == [False] * 10 and heard["terminated"] == [False] * 10
    assert heard["observation"][0].shape == (10,)


def test_lockstep_waits_for_the_agent_and_realtime_does_not() -> None:
    lockstep = GymWorld("Reacher-v5", config=GymWorldConfig(action_timeout=0.3, resend_interval=0.1))
    realtime = GymWorld("Reacher-v5", component_name="clock_world",
                        config=GymWorldConfig(clock="realtime", control_rate=200.0))
    launcher = _started(lockstep, realtime)
    try:
        waited = _episode(launcher, seed=1, max_steps=5)
        reply = launcher.transport.request("clock_world/execute_method",
                                           {"method": "run_episode", "kwargs": {"seed": 1, "max_steps": 5}}, timeout=30)
    finally:
        launcher.stop()
    assert waited["ended"] == "error" and "no action on 'action' within 0.3 s (lockstep)" in waited["reason"]
    assert reply["result"]["ended"] == "step_limit" and reply["result"]["steps"] == 5


def test_reset_is_an_action_and_publishes_the_first_observation() -> None:
    heard: list[Any] = []
    launcher = _started(GymWorld("Reacher-v5", cameras={}))
    sub = launcher.transport.create_subscription(Topic("observation", "Float64MultiArray"), heard.append)
    try:
        assert "reset" in launcher.components[0].available_actions()
        reply = launcher.transport.request("world/execute_method", {"method": "reset", "kwargs": {"seed": 3}},
                                           timeout=30)
        assert wait_for(lambda: len(heard) == 1, timeout=5)
    finally:
        sub.close()
        launcher.stop()
    assert reply["result"]["observation"] == pytest.approx(heard[0].tolist())


def test_actions_arrive_as_arrays_joint_states_or_twists() -> None:
    by_name = JointStateMsg(name=["b", "a"], position=[2.0, 1.0])
    assert action_vector(by_name, (2,), topic="act", world="w", joint_names=["a", "b"]).tolist() == [1.0, 2.0]
    twist = TwistMsg(linear=[0.1, 0.2, 0.3], angular=[0.0, 0.0, 0.5])
    assert action_vector(twist, (2,), topic="act", world="w").tolist() == [0.1, 0.2]
    assert action_vector([0.5, -0.5], (2,), topic="act", world="w").tolist() == [0.5, -0.5]
    with pytest.raises(AlgorithmFailure, match="world 'w': the action on 'act' has 3 value"):
        action_vector([1.0, 2.0, 3.0], (2,), topic="act", world="w")
    with pytest.raises(AlgorithmFailure, match="NaN"):
        action_vector(np.array([np.nan, 0.0]), (2,), topic="act", world="w")
    with pytest.raises(AlgorithmFailure, match=r"no position for joint\(s\) \['c'\]"):
        action_vector(by_name, (2,), topic="act", world="w", joint_names=["a", "c"])
    with pytest.raises(ConfigError, match="action_type must be one of"):
        GymWorld("Reacher-v5", action_type="String")
