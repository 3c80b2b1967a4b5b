"""An exported dataset of 5 episodes loads with LeRobot's own ``LeRobotDataset``, offline, frames as recorded.

Needs ``lerobot`` (and torch): the ``lerobot`` nox session installs them; elsewhere this module skips.
The dataset is read from its folder (``root=``) with ``HF_HUB_OFFLINE=1``: nothing is fetched.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

os.environ["HF_HUB_OFFLINE"] = "1"  # before huggingface_hub is imported (by lerobot)

pytest.importorskip("mcap", reason="pip install 'agents-core[record]'")
pytest.importorskip("av", reason="pip install 'agents-core[dataset]'")
lerobot_dataset = pytest.importorskip("lerobot.datasets.lerobot_dataset", reason="nox -s lerobot")

from agents_core.episodes import export_lerobot_dataset  # noqa: E402

from ..episodes.dataset_parts import FEATURES, FPS, HEIGHT, JOINT_NAMES, WIDTH, record_episodes  # noqa: E402

REPO_ID = "agents/episodes-test"


def test_five_exported_episodes_load_with_lerobot_dataset(tmp_path: Path) -> None:
    recorded = record_episodes(tmp_path / "episodes", episodes=5)
    root = tmp_path / "dataset"
    export_lerobot_dataset(recorded.directory, root, repo_id=REPO_ID, fps=FPS, frame_topic="joints",
                           features=FEATURES)
    dataset = lerobot_dataset.LeRobotDataset(REPO_ID, root=root)
    total = sum(recorded.steps)
    assert (len(dataset), dataset.num_episodes, dataset.fps) == (total, 5, FPS)
    assert dataset.meta.video_keys == ["observation.images.top"]
    assert dataset.meta.features["observation.state"]["names"] == JOINT_NAMES
    assert dataset.meta.stats["observation.state"]["mean"].shape == (3,)
    worst = 0.0
    index = 0
    for e, steps in enumerate(recorded.steps):
        for s in range(steps):
            item = dataset[index]
            assert item["episode_index"].item() == e and item["frame_index"].item() == s
            assert item["index"].item() == index
            assert item["timestamp"].item() == pytest.approx(s / FPS, abs=1e-6)
            assert item["task"] == recorded.tasks[e]
            np.testing.assert_array_equal(item["observation.state"].numpy(), recorded.states[e][s].astype(np.float32))
            np.testing.assert_array_equal(item["action"].numpy(), recorded.actions[e][s].astype(np.float32))
            image = item["observation.images.top"].numpy()  # C x H x W, float in [0, 1]
            assert image.shape == (3, HEIGHT, WIDTH)
            error = float(np.abs(image.transpose(1, 2, 0) * 255.0 - recorded.images[e][s]).mean())
            worst = max(worst, error)
            index += 1
    assert worst < 3.0, f"camera frames differ from the recorded ones by {worst:.2f} grey levels on average"


def test_a_policy_window_reads_across_frames(tmp_path: Path) -> None:
    """``delta_timestamps`` (how a policy asks for an action chunk) resolves within each episode."""
    recorded = record_episodes(tmp_path / "episodes", episodes=2, steps=8)
    root = tmp_path / "dataset"
    export_lerobot_dataset(recorded.directory, root, repo_id=REPO_ID, fps=FPS, frame_topic="joints",
                           features=FEATURES)
    window = [k / FPS for k in range(4)]
    dataset = lerobot_dataset.LeRobotDataset(REPO_ID, root=root, delta_timestamps={"action": window})
    item = dataset[6]  # episode 0, frame 6 of 8: the last two of the window are padding
    assert item["action"].shape == (4, 4)
    assert item["action_is_pad"].tolist() == [False, False, True, True]
    np.testing.assert_array_equal(item["action"][1].numpy(), recorded.actions[0][7].astype(np.float32))
