"""compare_runs (the verdict for B against A) and expect_success_rate (an evaluation as a pytest assertion)."""

from __future__ import annotations

from pathlib import Path

import pytest

from agents_core.evals.compare import compare_runs
from agents_core.evals.expect import expect_success_rate
from agents_core.evals.results import ResultsError, load_results
from agents_core.evals.stats import compare_success, wilson_interval

from .results_dirs import episode, info, make_run, write_dir


def test_a_clearly_worse_candidate_is_worse(tmp_path: Path) -> None:
    a = make_run(tmp_path / "a", [True] * 18 + [False] * 2, name="main", frames=False)
    b = make_run(tmp_path / "b", [True] * 6 + [False] * 14, name="change", frames=False)
    c = compare_runs(a, b)
    assert (c.verdict, c.worse) == ("worse", True)
    assert c.p_value == compare_success(18, 20, 6, 20) and c.p_value < 0.001
    assert (c.a.successes, c.a.n, c.b.successes, c.b.n) == (18, 20, 6, 20)
    assert (c.b.low, c.b.high) == wilson_interval(6, 20)
    assert c.difference == pytest.approx(-0.6) and c.same_seeds
    assert [seed for seed, _, _ in c.flipped] == list(range(6, 18))
    assert "B is worse than A" in c.describe()
    # The other way round B is better.
    assert compare_runs(b, a).verdict == "better"


def test_a_small_difference_is_no_significant_difference(tmp_path: Path) -> None:
    a = make_run(tmp_path / "a", [True] * 16 + [False] * 4, frames=False)
    b = make_run(tmp_path / "b", [True] * 13 + [False] * 7, frames=False)
    c = compare_runs(a, b)
    assert c.verdict == "no significant difference" and not c.worse and c.p_value > 0.05
    assert "not significantly different" in c.describe()


def test_alpha_decides_the_verdict(tmp_path: Path) -> None:
    a = make_run(tmp_path / "a", [True] * 15 + [False] * 5, frames=False)
    b = make_run(tmp_path / "b", [True] * 8 + [False] * 12, frames=False)
    p = compare_success(15, 20, 8, 20)
    assert 0.01 < p < 0.1  # between the two alphas below
    assert compare_runs(a, b, alpha=0.1).verdict == "worse"
    assert compare_runs(a, b, alpha=0.01).verdict == "no significant difference"
    for bad in (0, 1, -0.5, float("nan"), True):
        with pytest.raises(ValueError, match=r"alpha"):
            compare_runs(a, b, alpha=bad)


def test_different_seeds_are_noted_and_loaded_results_work_too(tmp_path: Path) -> None:
    a = make_run(tmp_path / "a", [True, True, False], seeds=[1, 2, 3], frames=False)
    b = make_run(tmp_path / "b", [False, False, True], seeds=[2, 3, 4], frames=False)
    c = compare_runs(load_results(a), load_results(b))
    assert not c.same_seeds and c.flipped == ((2, True, False),)
    assert "did not use the same seeds" in c.describe()


def test_an_unreadable_run_is_an_error(tmp_path: Path) -> None:
    a = make_run(tmp_path / "a", [True], frames=False)
    with pytest.raises(ResultsError, match=r"evaluation\.json does not exist"):
        compare_runs(a, tmp_path)


def test_expect_passes_at_or_over_the_threshold_and_returns_the_results(tmp_path: Path) -> None:
    out = make_run(tmp_path / "run", [True] * 16 + [False] * 4, frames=False)
    assert expect_success_rate(out, at_least=0.8).successes == 16
    expect_success_rate(load_results(out), 0.5)


def test_expect_fails_with_rate_interval_episodes_and_failed_seeds(tmp_path: Path) -> None:
    lines = [episode(i, i < 10, seed=100 + i) for i in range(18)]
    lines += [episode(18, False, seed=118, ended="error", reason="the env raised ValueError: bad action"),
              episode(19, False, seed=119, ended="world_died", reason="the world process exited")]
    out = write_dir(tmp_path / "run", info(episodes=20), lines)
    with pytest.raises(AssertionError) as caught:
        expect_success_rate(out, at_least=0.8)
    message = str(caught.value)
    low, high = wilson_interval(10, 20)
    assert "success rate 50.0 % is under 80 %" in message
    assert "10/20 succeeded" in message and f"{low * 100:.1f}-{high * 100:.1f} %" in message
    assert "failed seeds: 110, 111, 112, 113, 114, 115, 116, 117, 118, 119" in message
    assert "ended: success 10, step_limit 8, error 1, world_died 1" in message
    assert "the env raised ValueError: bad action" in message and str(out) in message


def test_expect_fails_an_empty_or_too_short_run(tmp_path: Path) -> None:
    out = write_dir(tmp_path / "run", info(episodes=20, finished=None, interrupted=True), [])
    with pytest.raises(AssertionError, match=r"only 0 episode"):
        expect_success_rate(out, at_least=0.0)
    out = make_run(tmp_path / "short", [True] * 3, frames=False)
    with pytest.raises(AssertionError, match=r"only 3 episode.*fewer than the 20 needed"):
        expect_success_rate(out, at_least=0.5, min_episodes=20)


def test_expect_lists_at_most_30_failed_seeds(tmp_path: Path) -> None:
    out = make_run(tmp_path / "run", [False] * 45, frames=False)
    with pytest.raises(AssertionError, match=r"29, \.\.\. \(15 more\)"):
        expect_success_rate(out, at_least=0.1)


@pytest.mark.parametrize("bad", [80, -0.1, 1.01, float("nan"), "0.8", None])
def test_expect_refuses_a_threshold_that_is_not_a_rate(tmp_path: Path, bad: object) -> None:
    out = make_run(tmp_path / "run", [True], frames=False)
    with pytest.raises(ValueError, match=r"between 0 and 1"):
        expect_success_rate(out, at_least=bad)  # type: ignore[arg-type]
