"""The report, compare and expect on real evaluations: Gymnasium's Reacher-v5, run by agents_core.evals.runner.

Runs where the runner (s7-sim's part of agents_core.evals), examples/evaluate_reacher.py and the
``sim`` extra (Gymnasium, MuJoCo) are all there; skipped, saying which is missing, otherwise. Five
lock-step episodes per agent on the memory transport: the expert succeeds on seeds 1000-1004 and
the random agent does not, the same on every machine (lock-step, seeded).
"""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path
from typing import Any

import pytest

from agents_core.evals.compare import compare_runs
from agents_core.evals.expect import expect_success_rate
from agents_core.evals.report import write_comparison_report
from agents_core.evals.results import load_results

from ..cli.helpers import cli

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
_MISSING = [m for m in ("gymnasium", "mujoco") if importlib.util.find_spec(m) is None]
if _MISSING:
    pytest.skip(f"{', '.join(_MISSING)} not installed: pip install 'agents-core[sim]'", allow_module_level=True)
if importlib.util.find_spec("agents_core.evals.runner") is None or not (EXAMPLES / "evaluate_reacher.py").is_file():
    pytest.skip("the evaluation runner or examples/evaluate_reacher.py is not in this checkout",
                allow_module_level=True)

EPISODES = 5


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    os.environ.setdefault("MUJOCO_GL", "egl")
    from agents_core.evals.runner import run_evaluation  # type: ignore[import-not-found,unused-ignore]  # noqa: PLC0415

    sys.path.insert(0, str(EXAMPLES))
    try:
        from evaluate_reacher import evaluation  # type: ignore[import-not-found,unused-ignore]  # noqa: PLC0415
    finally:
        sys.path.remove(str(EXAMPLES))
    root = tmp_path_factory.mktemp("reacher")
    return {agent: run_evaluation(evaluation(agent, EPISODES, seed=1000), root / agent, transport="memory",
                                  progress=False) for agent in ("expert", "random")}


def test_the_runner_s_output_reads_back_as_it_was_written(runs: dict[str, Any]) -> None:
    for run in runs.values():
        results = load_results(run.out_dir)
        assert results.complete and not results.partial_last_line and results.n == EPISODES
        assert [(e.seed, e.success, e.steps, e.ended) for e in results.episodes] == \
            [(r["seed"], r["success"], r["steps"], r["ended"]) for r in run.results]
        assert [list(e.rewards) for e in results.episodes] == [r["rewards"] for r in run.results]
        assert results.info.world == "Reacher-v5" and results.info.clock == "lockstep"
        assert all(results.frame_file(f) for e in results.episodes for f in e.frames)


def test_the_runner_wrote_a_report_with_its_numbers(runs: dict[str, Any]) -> None:
    expert = runs["expert"]
    page = (expert.out_dir / "report.html").read_text(encoding="utf-8")
    assert f'data-successes="{expert.successes}" data-n="{EPISODES}"' in page
    assert page.count("data:image/") >= 1 and "<script" not in page


def test_compare_and_expect_tell_the_expert_from_the_random_agent(runs: dict[str, Any], tmp_path: Path) -> None:
    expert, random = runs["expert"].out_dir, runs["random"].out_dir
    assert load_results(expert).successes == EPISODES and load_results(random).successes == 0
    comparison = compare_runs(expert, random)
    assert comparison.verdict == "worse" and comparison.same_seeds and len(comparison.flipped) == EPISODES
    expect_success_rate(expert, at_least=0.8)
    with pytest.raises(AssertionError, match=r"success rate 0\.0 % is under 80 %"):
        expect_success_rate(random, at_least=0.8)
    page = write_comparison_report(expert, random, tmp_path / "compare.html")
    assert 'data-verdict="worse"' in page.read_text(encoding="utf-8")
    done = cli("eval", "compare", str(expert), str(random))
    assert done.returncode == 1 and "B is worse than A" in done.stdout, done.stderr
