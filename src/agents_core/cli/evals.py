"""``agentsctl eval report | compare``: an evaluation's HTML report, and whether a change made it worse.

``agentsctl eval compare A B`` exits with status 1 when B's success rate is significantly lower
than A's (two-sided Fisher exact test at ``--alpha``), so a CI job can gate on it; 0 when it is not
(better, or no significant difference); 2 when a directory cannot be read or an option is wrong.
The evaluation modules are imported by the commands, not here: ``agentsctl`` stays quick to start.
``agentsctl eval run`` is registered on :data:`eval_app` by ``agents_core.cli.eval_run``.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from .connection import USAGE_ERROR, fail
from .output import print_json, print_table, say

if TYPE_CHECKING:
    from ..evals.results import EvaluationResults

__all__ = ["EXIT_WORSE", "eval_app"]

#: The exit status of ``agentsctl eval compare`` when B is significantly worse than A.
EXIT_WORSE = 1

eval_app = typer.Typer(help="Report on evaluations and compare two of them (did this change make it worse?).",
                       no_args_is_help=True)

JsonOpt = Annotated[bool, typer.Option("--json", help="print one JSON document instead of tables")]


def _load(out_dir: Path) -> EvaluationResults:
    from ..evals.results import ResultsError, load_results  # noqa: PLC0415 - imported when the command runs

    try:
        return load_results(out_dir)
    except ResultsError as exc:
        raise fail(str(exc), USAGE_ERROR) from None


def _summary(results: EvaluationResults) -> dict[str, Any]:
    from ..evals.stats import mean_interval, wilson_interval  # noqa: PLC0415

    low, high = wilson_interval(results.successes, results.n)
    reward = mean_interval(e.reward_sum for e in results.episodes)
    return {"name": results.info.name, "dir": str(results.out_dir), "episodes": results.n,
            "episodes_asked": results.info.episodes, "successes": results.successes,
            "success_rate": results.success_rate, "interval_95": [low, high], "mean_reward_sum": reward.mean,
            "complete": results.complete, "failed_seeds": list(results.failed_seeds)}


def _row(label: str, doc: dict[str, Any]) -> list[str]:
    low, high = doc["interval_95"]
    reward = "-" if doc["mean_reward_sum"] is None else f"{doc['mean_reward_sum']:.4g}"
    return [label, doc["name"], f"{doc['episodes']}/{doc['episodes_asked']}", str(doc["successes"]),
            f"{doc['success_rate'] * 100:.1f} %", f"{low * 100:.1f}-{high * 100:.1f} %", reward,
            "yes" if doc["complete"] else "no"]


_COLUMNS = ["", "name", "episodes", "successes", "rate", "95 % interval", "mean reward sum", "finished"]


@eval_app.command("report")
def report(out_dir: Annotated[Path, typer.Argument(help="an evaluation's output directory")],
           json_out: JsonOpt = False) -> None:
    """Write (or rewrite) DIR/report.html from DIR's results, print its path and a summary."""
    from ..evals.report import write_report  # noqa: PLC0415

    results = _load(out_dir)
    try:
        path = write_report(out_dir, results=results)
    except OSError as exc:
        raise fail(f"cannot write the report into {out_dir}: {exc}") from None
    summary = _summary(results)
    if json_out:
        print_json({**summary, "report": str(path)})
        return
    print_table("evaluation", _COLUMNS, [_row("", summary)])
    if results.failed_seeds:
        seeds = ", ".join(str(s) for s in results.failed_seeds[:30])
        say("failed seeds: ", seeds + (" ..." if len(results.failed_seeds) > 30 else ""))
    say("report: ", str(path))


@eval_app.command("compare")
def compare(dir_a: Annotated[Path, typer.Argument(help="the reference evaluation (A: before the change)")],
            dir_b: Annotated[Path, typer.Argument(help="the candidate evaluation (B: after the change)")],
            alpha: Annotated[float, typer.Option("--alpha", help="significance level of the test", min=1e-9,
                                                 max=0.5)] = 0.05,
            out: Annotated[Path | None, typer.Option("--out", "-o", help="also write the comparison as an HTML "
                                                                         "page to this file")] = None,
            json_out: JsonOpt = False) -> None:
    """Compare B's success rate with A's (Fisher exact test); exit status 1 when B is significantly worse.

    Exit status: 0 when B is not significantly worse (better, or no significant difference), 1 when it
    is, 2 when a directory cannot be read.
    """
    from ..evals.compare import compare_runs  # noqa: PLC0415
    from ..evals.report import write_comparison_report  # noqa: PLC0415

    a, b = _load(dir_a), _load(dir_b)
    comparison = compare_runs(a, b, alpha=alpha)
    path = None
    if out is not None:
        try:
            path = write_comparison_report(a, b, out, alpha=alpha)
        except OSError as exc:
            raise fail(f"cannot write the comparison to {out}: {exc}") from None
    if json_out:
        print_json({"a": _summary(a), "b": _summary(b), "p_value": comparison.p_value, "alpha": comparison.alpha,
                    "verdict": comparison.verdict, "difference": comparison.difference,
                    "same_seeds": comparison.same_seeds,
                    "flipped": [{"seed": s, "a": x, "b": y} for s, x, y in comparison.flipped],
                    "report": None if path is None else str(path)})
    else:
        print_table("comparison", _COLUMNS, [_row("A", _summary(a)), _row("B", _summary(b))])
        say(f"difference {comparison.difference * 100:+.1f} points, Fisher exact p = {comparison.p_value:.4g} "
            f"(alpha {comparison.alpha:g}): ", (f"B is {comparison.verdict_text()}",
                                                "bold red" if comparison.worse else "bold"))
        if not comparison.same_seeds:
            say("note: the two runs did not use the same seeds")
        if path is not None:
            say("report: ", str(path))
    if comparison.worse:
        raise typer.Exit(EXIT_WORSE)
