"""The parts of an evaluation that need no physics: seeds, thumbnails, episode hooks (on the small test env)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core.errors import ConfigError
from agents_core.evals import Evaluation, run_evaluation
from agents_core.sim import GymWorld, RandomAgent
from agents_core.sim.thumbnails import Thumbnails

from .hostile_envs import ENV_ID


def _evaluation(**kwargs: Any) -> Evaluation:
    return Evaluation(name="small", world=lambda: GymWorld(ENV_ID), recipe=lambda: [RandomAgent([0.1], [1.0])],
                      **kwargs)


def test_seeds_follow_the_evaluation_or_the_overrides() -> None:
    assert _evaluation(episodes=3, seed=10).seed_list() == [10, 11, 12]
    assert _evaluation(episodes=3, seed=10).seed_list(episodes=2, seed=0) == [0, 1]
    assert _evaluation(episodes=2, seeds=[7, 9, 11]).seed_list() == [7, 9]
    with pytest.raises(ConfigError, match="4 episodes asked, 3 seeds given"):
        _evaluation(seeds=[7, 9, 11]).seed_list(episodes=4)
    with pytest.raises(ConfigError, match="episodes: expected an int >= 1"):
        _evaluation(episodes=0)
    with pytest.raises(ConfigError, match="max_wall_s: expected a number > 0"):
        _evaluation(max_wall_s=-1.0)


def test_thumbnails_are_evenly_spaced_and_bounded(tmp_path: Path) -> None:
    thumbs = Thumbnails(4)
    for step in range(1000):
        frame = np.zeros((6, 8, 3), np.uint8)
        frame[0, 0, :2] = divmod(step, 256)
        thumbs.add({"camera": frame})
        assert len(thumbs._frames) < 16  # bounded whatever the episode's length
    chosen = [256 * int(frame[0, 0, 0]) + int(frame[0, 0, 1]) for frame in thumbs.chosen()]
    assert len(chosen) == 4 and chosen[0] == 0 and chosen[-1] == 999 and chosen == sorted(chosen)
    assert 200 < chosen[1] < 450 and 550 < chosen[2] < 800  # evenly spaced, near thirds
    names = thumbs.write(tmp_path / "frames", "ep0001")
    assert names == [f"frames/ep0001_{i:02d}.jpg" for i in range(4)]
    assert all((tmp_path / name).stat().st_size > 0 for name in names)


def test_episode_hooks_are_called_around_each_episode(tmp_path: Path) -> None:
    calls: list[tuple[str, Any]] = []

    class Hooks:
        def on_episode_start(self, episode: int, seed: int) -> None:
            calls.append(("start", (episode, seed)))

        def on_episode_end(self, result: dict[str, Any]) -> None:
            calls.append(("end", (result["episode"], result["seed"], result["ended"])))

    run = run_evaluation(_evaluation(episodes=2, seed=20), tmp_path, episode_hooks=[Hooks()], progress=False)
    assert calls == [("start", (0, 20)), ("end", (0, 20, "success")), ("start", (1, 21)),
                     ("end", (1, 21, "success"))]
    lines = [json.loads(line) for line in (tmp_path / "results.jsonl").read_text(encoding="utf-8").splitlines()]
    assert lines == run.results
    assert set(lines[0]) == {"episode", "seed", "success", "reward_sum", "steps", "time_to_success_s",
                             "steps_to_success", "wall_s", "ended", "reason", "rewards", "frames"}
