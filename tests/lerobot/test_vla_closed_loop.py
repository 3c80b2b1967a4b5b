"""The loop closed with LeRobot itself: a world's episodes become a dataset, a policy built from it drives the world.

1. A scripted expert drives the real-time :mod:`toy world <tests.lerobot.toy_world>` (a Gymnasium env on the
   memory transport); :class:`~agents_core.episodes.EpisodeRecordingHooks` records each episode, which are
   exported as a LeRobot dataset and loaded back with ``LeRobotDataset``.
2. An ACT policy with random weights is built from that dataset's features and statistics and served by
   LeRobot's own ``lerobot.async_inference.policy_server`` (a child process, 127.0.0.1).
3. The ``VLA`` component, through ``LeRobotClient``, drives the same world episode after episode (one goal each),
   those episodes recorded too; each is scored by the task's rule. Untrained, the policy is expected to score
   near zero: what is checked is the plumbing (every goal runs its steps, the world follows the policy's
   commands, the episodes export) and that the score is reported, not a threshold on it.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

os.environ["HF_HUB_OFFLINE"] = "1"

pytest.importorskip("mcap", reason="pip install 'agents-core[record]'")
pytest.importorskip("grpc", reason="pip install 'agents-core[vla]'")
pytest.importorskip("gymnasium", reason="nox -s lerobot")
lerobot_dataset = pytest.importorskip("lerobot.datasets.lerobot_dataset", reason="nox -s lerobot")

from agents_core import Launcher  # noqa: E402
from agents_core.clients.lerobot import LeRobotClient  # noqa: E402
from agents_core.components import VLA  # noqa: E402
from agents_core.config import VLAConfig  # noqa: E402
from agents_core.episodes import EpisodeRecordingHooks, export_lerobot_dataset  # noqa: E402
from agents_core.messages import JointStateMsg  # noqa: E402
from agents_core.models import LeRobotPolicy  # noqa: E402
from agents_core.transport import MemoryTransport  # noqa: E402
from agents_core.transport.goals import GoalStatus  # noqa: E402

from .policy_parts import build_act_checkpoint, free_port, policy_server  # noqa: E402
from .toy_world import CAMERA, COMMANDS, JOINTS, STATE, RealTimeWorld  # noqa: E402

pytestmark = pytest.mark.slow

REPO_ID = "agents/toy-reach"
FPS = 20
STEPS = 30
TASK = "reach the red square"
FEATURES = {"observation.state": "joint_states", "observation.images.top": "top", "action": "joint_commands"}


def _expert_episodes(directory: Path, seeds: list[int]) -> list[dict[str, Any]]:
    transport = MemoryTransport()
    world = RealTimeWorld(transport, rate=FPS)
    hooks = EpisodeRecordingHooks.attached(transport, [STATE, CAMERA, COMMANDS], directory, task=TASK)
    commands = transport.create_publisher(COMMANDS)
    results = []
    try:
        for episode, seed in enumerate(seeds):
            target = world.reset(seed)
            hooks.on_episode_start(episode, seed)
            while world.steps < STEPS:
                commands.publish(JointStateMsg(name=JOINTS, position=target))  # the expert knows the target
                time.sleep(0.5 / FPS)
            world.stop()
            results.append({"episode": episode, "seed": seed, "success": world.env.success(), "steps": world.steps})
            hooks.on_episode_end(results[-1])
    finally:
        hooks.close()
        world.close()
        transport.close()
    return results


def _vla(checkpoint: Path, info_file: Path, port: int) -> VLA:
    model = LeRobotPolicy(name="toy_act", policy_type="act", checkpoint=str(checkpoint), actions_per_chunk=10,
                          policy_device="cpu", dataset_info_file=str(info_file))
    model.load_dataset_info()
    client = LeRobotClient(model, port=port, allow_pickle=True, inference_timeout=60)
    config = VLAConfig(joint_names_map={n: n for n in JOINTS}, camera_inputs_map={"top": CAMERA.name},
                       observation_sending_rate=10.0, action_sending_rate=float(FPS), state_timeout=2.0)
    return VLA(inputs=[STATE, CAMERA], outputs=[COMMANDS], model_client=client, config=config, trigger=None,
               component_name="arm_vla")


def test_a_policy_built_from_recorded_episodes_drives_the_world_through_lerobot(tmp_path: Path) -> None:
    expert = _expert_episodes(tmp_path / "expert", seeds=[1, 2, 3, 4, 5])
    assert sum(r["success"] for r in expert) >= 4, expert  # the expert reaches: the rule can be met
    dataset_root = tmp_path / "dataset"
    summary = export_lerobot_dataset(tmp_path / "expert", dataset_root, repo_id=REPO_ID, fps=FPS,
                                     frame_topic="joint_states", features=FEATURES)
    dataset = lerobot_dataset.LeRobotDataset(REPO_ID, root=dataset_root)
    assert dataset.num_episodes == 5 and len(dataset) == summary.frames >= 5 * (STEPS - 2)
    assert dataset.meta.features["action"]["names"] == JOINTS

    checkpoint = build_act_checkpoint(dataset_root, REPO_ID, tmp_path / "act")
    port = free_port()
    results: list[dict[str, Any]] = []
    with policy_server(tmp_path / "policy_server.log", port):
        launcher = Launcher("memory")
        launcher.add_pkg(components=[_vla(checkpoint, dataset_root / "meta" / "info.json", port)])
        with launcher:
            transport = launcher.transport
            world = RealTimeWorld(transport, rate=FPS)
            hooks = EpisodeRecordingHooks.attached(transport, [STATE, CAMERA, COMMANDS], tmp_path / "vla", task=TASK)
            try:
                for episode, seed in enumerate([11, 12, 13]):
                    world.reset(seed)
                    hooks.on_episode_start(episode, seed)
                    before = world.commands_received
                    started = time.monotonic()
                    goal = transport.send_goal("arm_vla", "VisionLanguageAction",
                                               {"task": TASK, "max_steps": STEPS}, timeout=30.0)
                    status, outcome = goal.result(timeout=240)
                    world.stop()
                    results.append({"episode": episode, "seed": seed, "success": world.env.success(),
                                    "status": getattr(status, "name", str(status)), "goal_steps": outcome.get("steps"),
                                    "commands": world.commands_received - before, "world_steps": world.steps,
                                    "wall_s": round(time.monotonic() - started, 2),
                                    "distance": float(np.abs(world.env.q - world.env.target).max())})
                    hooks.on_episode_end(results[-1])
                    log = (tmp_path / "policy_server.log").read_text()[-3000:]
                    assert status == GoalStatus.SUCCEEDED, (outcome, log)
                    assert outcome["steps"] == STEPS
            finally:
                hooks.close()
                world.close()
    (tmp_path / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in results))
    successes = sum(r["success"] for r in results)
    print(f"\nexpert: {sum(r['success'] for r in expert)}/5 reached; untrained ACT through LeRobot's policy server: "
          f"{successes}/{len(results)} reached; {results}")
    for r in results:
        assert r["commands"] >= STEPS // 2, r  # the world followed the policy's commands
    vla_summary = export_lerobot_dataset(tmp_path / "vla", tmp_path / "vla_dataset", repo_id="agents/toy-vla", fps=FPS,
                                         frame_topic="joint_states", features=FEATURES)
    assert vla_summary.episodes == 3 and not vla_summary.skipped  # the policy's own episodes are data too
