"""3(b) on the framework's own Gymnasium world and evaluation runner (``agents_core.sim`` / ``agents_core.evals``).

The same loop as ``test_vla_closed_loop.py``, with ``GymWorld`` (lock-step) around the toy reaching env
instead of the test's own stepping, and ``run_evaluation`` scoring the episodes by the env's rule:

1. a scripted expert (it gets the target as privileged state) is evaluated over 5 seeds, an
   :class:`~agents_core.episodes.EpisodeRecorderComponent` in the recipe recording each episode through
   :class:`~agents_core.episodes.EpisodeRecordingHooks`; the episodes are exported and load in ``LeRobotDataset``;
2. a random-weight ACT built from that dataset, served by LeRobot's policy server, drives the world through the
   ``VLA`` component and ``LeRobotClient`` (one goal per episode, started by a hook), scored by the same rule:
   near zero expected; the test checks that each episode ran its steps on the policy's commands.

Skips where ``agents_core.sim`` is absent (before the sim branch is merged).
"""

from __future__ import annotations

import json
import os
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

os.environ["HF_HUB_OFFLINE"] = "1"

pytest.importorskip("mcap", reason="pip install 'agents-core[record]'")
pytest.importorskip("grpc", reason="pip install 'agents-core[vla]'")
pytest.importorskip("gymnasium", reason="nox -s lerobot")
pytest.importorskip("agents_core.sim", reason="the framework's Gymnasium world (agents_core.sim)")
lerobot_dataset = pytest.importorskip("lerobot.datasets.lerobot_dataset", reason="nox -s lerobot")

from agents_core import Component, Topic  # noqa: E402
from agents_core.clients.lerobot import LeRobotClient  # noqa: E402
from agents_core.components import VLA  # noqa: E402
from agents_core.config import VLAConfig  # noqa: E402
from agents_core.episodes import (  # noqa: E402
    EpisodeRecorderComponent,
    EpisodeRecorderConfig,
    EpisodeRecordingHooks,
    export_lerobot_dataset,
)
from agents_core.evals import Evaluation, run_evaluation  # noqa: E402
from agents_core.messages import JointStateMsg  # noqa: E402
from agents_core.models import LeRobotPolicy  # noqa: E402
from agents_core.sim import GymWorld, GymWorldConfig  # noqa: E402

from .policy_parts import build_act_checkpoint, free_port, policy_server  # noqa: E402
from .toy_world import JOINTS, register, target_of  # noqa: E402

pytestmark = pytest.mark.slow

TASK = "reach the red square"
STEPS = 25
FEATURES = {"observation.state": "joint_states", "observation.images.top": "top", "action": "joint_commands"}
RECORDED = [Topic("joint_states", "JointState"), Topic("top", "Image"), Topic("joint_commands", "JointState")]


class ToyExpert(Component):
    """Commands the target it reads at the end of the observation (the world's privileged state)."""

    def __init__(self, **kwargs: Any) -> None:
        observation = Topic("observation", "Float64MultiArray")
        super().__init__(inputs=[observation], outputs=[Topic("joint_commands", "JointState")], trigger=observation,
                         component_name="toy_expert", **kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        vector = next(iter(self.trig_callbacks.values())).get_output()
        if vector is not None:
            self.publishers_dict["joint_commands"].publish(JointStateMsg(name=JOINTS, position=vector[-2:]))


def _world() -> GymWorld:
    return GymWorld(register(), action_topic="joint_commands", action_type="JointState", joint_names=JOINTS,
                    cameras={"top": "render"}, privileged_state=target_of,
                    config=GymWorldConfig(clock="lockstep", max_steps=STEPS, thumbnails=0, action_timeout=30.0))


def _recorder(directory: Path) -> EpisodeRecorderComponent:
    return EpisodeRecorderComponent(inputs=RECORDED, component_name="episodes",
                                    config=EpisodeRecorderConfig(directory=str(directory)))


class GoalPerEpisode:
    """Episode hooks that give the VLA one goal per episode, cancelled at its end.

    The runner calls ``on_episode_start`` before the world resets, and a VLA goal needs a fresh state:
    the goal is sent from a thread once the reset's first JointState has arrived.
    """

    def __init__(self, vla: VLA) -> None:
        self.vla = vla
        self.goal: Any = None
        self._fresh = threading.Event()
        self._thread: threading.Thread | None = None
        self._subscription: Any = None

    def _send_when_fresh(self) -> None:
        if self._fresh.wait(30.0):
            self.goal = self.vla.transport.send_goal("arm_vla", "VisionLanguageAction",
                                                     {"task": TASK, "max_steps": 10_000}, timeout=30.0)

    def on_episode_start(self, episode: int, seed: int) -> None:
        if self._subscription is None:
            self._subscription = self.vla.transport.create_subscription(RECORDED[0], lambda _: self._fresh.set())
        self._fresh.clear()
        self.goal = None
        self._thread = threading.Thread(target=self._send_when_fresh, daemon=True)
        self._thread.start()

    def on_episode_end(self, result: dict[str, Any]) -> None:
        if self._thread is not None:
            self._thread.join(timeout=35.0)
        if self.goal is not None:
            self.goal.cancel(timeout=10.0)
            self.goal.result(timeout=30.0)


def _results(out: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]


def test_the_vla_drives_the_framework_s_world_and_is_scored(tmp_path: Path) -> None:
    expert_recorder = _recorder(tmp_path / "expert")
    expert = Evaluation(name="toy expert", world=_world, recipe=lambda: [ToyExpert(), expert_recorder],
                        episodes=5, seed=1, max_steps=STEPS)
    run_evaluation(expert, tmp_path / "eval_expert", episode_hooks=[
        EpisodeRecordingHooks.for_component(expert_recorder, task=TASK)], progress=False, report=False)
    expert_lines = _results(tmp_path / "eval_expert")
    assert sum(line["success"] for line in expert_lines) >= 4, expert_lines

    root = tmp_path / "dataset"
    summary = export_lerobot_dataset(tmp_path / "expert", root, repo_id="agents/toy-sim", fps=20,
                                     frame_topic="joint_states", features=FEATURES)
    dataset = lerobot_dataset.LeRobotDataset("agents/toy-sim", root=root)
    assert dataset.num_episodes == 5 and len(dataset) == summary.frames >= 5 * 2  # the expert ends episodes early
    first = dataset[0]
    assert first["observation.images.top"].shape[0] == 3 and first["action"].shape == (2,)

    checkpoint = build_act_checkpoint(root, "agents/toy-sim", tmp_path / "act")
    port = free_port()
    model = LeRobotPolicy(name="toy_act", policy_type="act", checkpoint=str(checkpoint), actions_per_chunk=10,
                          policy_device="cpu", dataset_info_file=str(root / "meta" / "info.json"))
    model.load_dataset_info()
    vla = VLA(inputs=[RECORDED[0], RECORDED[1]], outputs=[RECORDED[2]], trigger=None, component_name="arm_vla",
              model_client=LeRobotClient(model, port=port, allow_pickle=True, inference_timeout=60),
              config=VLAConfig(joint_names_map={n: n for n in JOINTS}, camera_inputs_map={"top": "top"},
                               observation_sending_rate=10.0, action_sending_rate=20.0, state_timeout=5.0))
    vla_recorder = _recorder(tmp_path / "vla")
    policy = Evaluation(name="untrained ACT", world=_world, recipe=lambda: [vla, vla_recorder], episodes=3, seed=11,
                        max_steps=STEPS, recipe_name="VLA + LeRobotClient -> LeRobot policy server (random ACT)")
    with policy_server(tmp_path / "policy_server.log", port):
        run_evaluation(policy, tmp_path / "eval_vla", episode_hooks=[
            EpisodeRecordingHooks.for_component(vla_recorder, task=TASK), GoalPerEpisode(vla)],
            progress=False, report=False)
    lines = _results(tmp_path / "eval_vla")
    print(f"\nexpert {sum(line['success'] for line in expert_lines)}/5, untrained ACT "
          f"{sum(line['success'] for line in lines)}/{len(lines)}: "
          f"{[(line['seed'], line['success'], line['steps'], line['ended']) for line in lines]}")
    assert len(lines) == 3
    for line in lines:
        assert line["ended"] in ("step_limit", "success", "truncated", "terminated"), line
        assert line["steps"] >= STEPS // 2 or line["success"], line
        assert np.isfinite(line["reward_sum"])
    vla_data = export_lerobot_dataset(tmp_path / "vla", tmp_path / "vla_dataset", repo_id="agents/toy-vla", fps=20,
                                      frame_topic="joint_states", features=FEATURES)
    assert vla_data.episodes == 3
