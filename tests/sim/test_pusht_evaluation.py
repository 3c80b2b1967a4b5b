"""Push-T's random agent on each transport, scored by Push-T's own rule (``info["is_success"]``): the
world's episodes are those of the same agent stepping the environment directly."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from typing import Any

import pytest

from agents_core.evals import Evaluation, run_evaluation
from agents_core.sim import GymWorld, RandomAgent

from .transports import TRANSPORTS, transport_options

pytestmark = pytest.mark.skipif(importlib.util.find_spec("gym_pusht") is None,
                                reason="gym-pusht not installed: pip install 'agents-core[sim]'")

ENV = "gym_pusht/PushT-v0"
KWARGS = {"obs_type": "state"}
STEPS, SEEDS = 100, [3, 4, 5]


def _agent() -> RandomAgent:
    return RandomAgent([0.0, 0.0], [512.0, 512.0], seed=11)


def _direct(seeds: list[int]) -> list[dict[str, Any]]:
    from agents_core.sim.env_host import make_env  # noqa: PLC0415

    agent, env = _agent(), make_env(ENV, KWARGS, None)
    try:
        episodes = []
        for seed in seeds:
            observation, _ = env.reset(seed=seed)
            rewards, success = [], False
            for _ in range(STEPS):
                observation, reward, terminated, _truncated, info = env.step(agent.act(observation))
                rewards.append(float(reward))
                success = success or bool(info["is_success"])
                if terminated:
                    break
            episodes.append({"rewards": rewards, "success": success})
        return episodes
    finally:
        env.close()


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_pusht_random_agent_scored_by_its_own_rule(transport: str, tmp_path: Path) -> None:
    evaluation = Evaluation(name="pusht-random", world=lambda: GymWorld(ENV, env_kwargs=KWARGS),
                            recipe=lambda: [_agent()], episodes=len(SEEDS), seeds=SEEDS, max_steps=STEPS)
    run = run_evaluation(evaluation, tmp_path, transport=transport, transport_options=transport_options(transport),
                         progress=False)
    meta = json.loads((tmp_path / "evaluation.json").read_text(encoding="utf-8"))
    assert meta["success_rule"] == "the environment's own rule (info['is_success'])"
    assert [r["ended"] for r in run.results] == ["step_limit"] * len(SEEDS)
    assert [{"rewards": r["rewards"], "success": r["success"]} for r in run.results] == _direct(SEEDS)
    assert run.success_rate <= 0.34
    assert all(len(r["frames"]) == 8 for r in run.results)
