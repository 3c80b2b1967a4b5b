"""Reacher-v5 scored on each transport in lock-step: the scripted expert succeeds, the random agent does not,
and the same seeds give the same episodes twice (and on every transport)."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path
from typing import Any

import pytest

from agents_core.errors import ConfigError
from agents_core.evals import run_evaluation
from agents_core.evals.compare import compare_runs
from agents_core.evals.expect import expect_success_rate, success_summary
from agents_core.evals.report import write_comparison_report
from agents_core.evals.results import load_results
from agents_core.evals.stats import wilson_interval

from .transports import TRANSPORTS, transport_options

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "examples"))
from evaluate_reacher import ReacherExpert, evaluation

EPISODES = 20
#: Episodes run a second time, which must come out the same.
AGAIN = 6


def _headline(report: Path) -> tuple[int, int, float, float, float]:
    """(successes, episodes, rate, interval low, interval high) as the report page states them."""
    page = report.read_text(encoding="utf-8")
    counts = re.search(r'data-successes="(\d+)" data-n="(\d+)"', page)
    rate = re.search(r'data-rate="([^"]+)"', page)
    interval = re.search(r'id="interval" data-low="([^"]+)" data-high="([^"]+)"', page)
    assert counts and rate and interval, "the report has no success headline"
    return (int(counts[1]), int(counts[2]), float(rate[1]), float(interval[1]), float(interval[2]))


def _reported_as_measured(out_dir: Path, successes: int) -> tuple[float, float]:
    """The report of ``out_dir`` states ``successes`` of EPISODES with their 95 % Wilson interval; returns it."""
    found, n, rate, low, high = _headline(out_dir / "report.html")
    assert (found, n) == (successes, EPISODES) and rate == pytest.approx(successes / EPISODES)
    assert (low, high) == pytest.approx(wilson_interval(successes, EPISODES))
    assert low <= rate <= high
    return low, high


def _comparable(path: Path) -> list[dict[str, Any]]:
    lines = [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines()]
    return [{k: v for k, v in line.items() if k != "wall_s"} for line in lines]


@pytest.mark.slow
@pytest.mark.parametrize("transport", TRANSPORTS)
def test_expert_beats_random_and_repeats(transport: str, tmp_path: Path) -> None:
    expert = run_evaluation(evaluation("expert", EPISODES, seed=1000), tmp_path / "expert", transport=transport,
                            transport_options=transport_options(transport), progress=False)
    random = run_evaluation(evaluation("random", EPISODES, seed=1000), tmp_path / "random", transport=transport,
                            transport_options=transport_options(transport), progress=False)
    run_evaluation(evaluation("random", AGAIN, seed=1000), tmp_path / "again", transport=transport,
                   transport_options=transport_options(transport), progress=False)
    assert len(expert.results) == len(random.results) == EPISODES
    assert expert.success_rate >= 0.8, [(r["seed"], r["ended"], r["reason"]) for r in expert.results]
    assert random.success_rate <= 0.1
    assert all(r["ended"] == "truncated" and r["steps"] == 50 for r in expert.results + random.results)
    first = _comparable(tmp_path / "random" / "results.jsonl")[:AGAIN]
    assert _comparable(tmp_path / "again" / "results.jsonl") == first
    meta = json.loads((tmp_path / "expert" / "evaluation.json").read_text(encoding="utf-8"))
    assert meta["transport"] == transport and meta["clock"] == "lockstep" and meta["episodes"] == EPISODES
    assert meta["seeds"] == list(range(1000, 1000 + EPISODES)) and meta["finished"] and not meta["interrupted"]
    assert "below 0.02 at the end" in meta["success_rule"]
    first = expert.results[0]
    assert first["frames"] and all((tmp_path / "expert" / f).is_file() for f in first["frames"])
    assert first["steps_to_success"] is not None and first["time_to_success_s"] == pytest.approx(
        first["steps_to_success"] * 0.02)
    # The framework changes nothing: the same expert stepping the env directly gets the same rewards.
    assert [r["rewards"] for r in expert.results] == _direct_rewards(range(1000, 1000 + EPISODES))
    _the_reports_say_so(tmp_path, expert.successes, random.successes)


def _the_reports_say_so(tmp_path: Path, expert_successes: int, random_successes: int) -> None:
    """Each report states its rate with its interval; the comparison tells the two agents apart, significantly."""
    expert_dir, random_dir = tmp_path / "expert", tmp_path / "random"
    expert_low, _ = _reported_as_measured(expert_dir, expert_successes)
    _, random_high = _reported_as_measured(random_dir, random_successes)
    assert random_high < expert_low  # the intervals do not overlap
    expect_success_rate(expert_dir, at_least=0.8, min_episodes=EPISODES)
    with pytest.raises(AssertionError, match="is under 80 %"):
        expect_success_rate(random_dir, at_least=0.8, min_episodes=EPISODES)
    comparison = compare_runs(expert_dir, random_dir)
    assert comparison.verdict == "worse" and comparison.same_seeds and comparison.p_value < 1e-4
    page = write_comparison_report(expert_dir, random_dir, tmp_path / "compare.html").read_text(encoding="utf-8")
    assert 'data-verdict="worse"' in page
    # What the closing note quotes: each agent's rate and interval, as the expect helper words it.
    print(success_summary(load_results(expert_dir)), "|", success_summary(load_results(random_dir)),
          f"| p = {comparison.p_value:.3g}")


def _direct_rewards(seeds: range) -> list[list[float]]:
    import gymnasium  # noqa: PLC0415

    agent = ReacherExpert()
    env = gymnasium.make("Reacher-v5")
    try:
        episodes = []
        for seed in seeds:
            observation, _ = env.reset(seed=seed)
            rewards = []
            for _ in range(50):
                observation, reward, _terminated, _truncated, _ = env.step(agent.act(observation))
                rewards.append(float(reward))
            episodes.append(rewards)
        return episodes
    finally:
        env.close()


def test_parallel_worlds_give_the_same_episodes(tmp_path: Path) -> None:
    one = run_evaluation(evaluation("random", 6, seed=50), tmp_path / "one", progress=False)
    two = run_evaluation(evaluation("random", 6, seed=50), tmp_path / "two", progress=False, workers=2)
    strip = [{k: v for k, v in r.items() if k not in ("wall_s", "frames")} for r in one.results]
    assert [{k: v for k, v in r.items() if k not in ("wall_s", "frames")} for r in two.results] == strip
    assert sorted(_comparable(tmp_path / "two" / "results.jsonl"), key=lambda r: r["episode"]) == \
        _comparable(tmp_path / "one" / "results.jsonl")
    with pytest.raises(ConfigError, match="only the memory transport keeps apart"):
        run_evaluation(evaluation("random", 2), tmp_path / "z", transport="zenoh", workers=2)
