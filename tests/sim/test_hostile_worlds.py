"""An environment that raises, hangs or returns NaN ends its episode with a reason, and the evaluation goes on;
a world process that dies is counted as ``world_died`` and the next episode runs on its respawn."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents_core.evals import Evaluation, run_evaluation
from agents_core.sim import GymWorld, GymWorldConfig, RandomAgent

from .hostile_envs import DIES, ENV_ID, HANGS, NAN, RAISES
from .transports import TRANSPORTS, transport_options


def _world() -> GymWorld:
    return GymWorld(ENV_ID, config=GymWorldConfig(step_timeout=1.0, action_timeout=10.0))


def _evaluation(seeds: list[int]) -> Evaluation:
    return Evaluation(name="hostile", world=_world, recipe=lambda: [RandomAgent([0.1], [1.0])],
                      episodes=len(seeds), seeds=seeds)


def test_raising_hanging_and_nan_envs_end_their_episode_only(tmp_path: Path) -> None:
    run = run_evaluation(_evaluation([0, RAISES, HANGS, NAN, 0]), tmp_path, progress=False)
    ended = [(r["ended"], r["steps"]) for r in run.results]
    assert ended == [("success", 5), ("error", 2), ("error", 2), ("error", 2), ("success", 5)]
    reasons = [r["reason"] for r in run.results]
    assert reasons[0] is None and reasons[4] is None
    assert "raised in step: RuntimeError: the simulator exploded" in reasons[1]
    assert "step took longer than 1 s" in reasons[2]
    assert "non-finite value: observation[1] is nan" in reasons[3]
    lines = (tmp_path / "results.jsonl").read_text(encoding="utf-8").splitlines()
    assert [json.loads(line)["episode"] for line in lines] == [0, 1, 2, 3, 4]
    assert run.results[0]["steps_to_success"] == 5 and run.results[0]["time_to_success_s"] == pytest.approx(0.5)


def test_an_agent_that_never_answers_ends_the_episode_in_lockstep(tmp_path: Path) -> None:
    evaluation = Evaluation(name="silent", recipe=lambda: [],
                            world=lambda: GymWorld(ENV_ID, config=GymWorldConfig(action_timeout=0.3,
                                                                                 resend_interval=0.1)),
                            episodes=2, seed=0)
    run = run_evaluation(evaluation, tmp_path, progress=False)
    assert [r["ended"] for r in run.results] == ["error", "error"]
    assert "no action on 'action' within 0.3 s" in run.results[0]["reason"]


# The cross-process transports. On ROS 2 the request to the dead world is never answered and waits out its timeout
# (an hour and more here): the next episode's request must not queue behind it.
@pytest.mark.parametrize("transport", [t for t in TRANSPORTS if t.values[0] != "memory"])
def test_a_world_process_that_dies_is_counted_not_waited_for(transport: str, tmp_path: Path) -> None:
    run = run_evaluation(_evaluation([0, DIES, 0]), tmp_path, transport=transport,
                         transport_options=transport_options(transport), world_process=True, progress=False)
    assert [r["ended"] for r in run.results] == ["success", "world_died", "success"]
    assert "died" in run.results[1]["reason"]
    assert run.results[1]["wall_s"] < 20
