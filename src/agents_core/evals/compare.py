"""Comparing two evaluations: "did this change make it worse?", answered with a significance test.

A is the reference (the main branch, the old policy), B the candidate. :func:`compare_runs` gives
each side's success rate with its Wilson interval, the two-sided Fisher exact p-value that both
share one rate, and a verdict for B: ``"better"`` or ``"worse"`` when ``p < alpha``, else
``"no significant difference"`` (which is not proof that they are the same: with 20 episodes a
side only large differences can be told apart). Seeds both runs share whose outcome differs are
listed, so the episodes that changed can be looked at.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from .results import EvaluationResults, load_results
from .stats import compare_success, wilson_interval

__all__ = ["BETTER", "NO_DIFFERENCE", "WORSE", "Comparison", "RunSummary", "compare_runs", "summarize_run"]

BETTER = "better"
WORSE = "worse"
NO_DIFFERENCE = "no significant difference"


@dataclass(frozen=True)
class RunSummary:
    """One evaluation's success rate with its interval."""

    name: str
    out_dir: Path
    n: int
    successes: int
    rate: float
    low: float
    high: float
    confidence: float = 0.95

    def describe(self) -> str:
        """``name: 15/20 succeeded, 75.0 % (95 % interval 53.1-88.8 %)``."""
        return (f"{self.name}: {self.successes}/{self.n} succeeded, {self.rate * 100:.1f} % "
                f"({self.confidence * 100:g} % interval {self.low * 100:.1f}-{self.high * 100:.1f} %)")


@dataclass(frozen=True)
class Comparison:
    """A against B: both rates, the p-value, and the verdict for B at ``alpha``."""

    a: RunSummary
    b: RunSummary
    p_value: float
    alpha: float
    verdict: str
    #: Whether both ran the same seeds (then the difference is the change's, not the draw's).
    same_seeds: bool
    #: (seed, A succeeded, B succeeded) for the seeds both ran whose outcome differs.
    flipped: tuple[tuple[int, bool, bool], ...] = ()

    @property
    def difference(self) -> float:
        """B's rate minus A's."""
        return self.b.rate - self.a.rate

    @property
    def worse(self) -> bool:
        """Whether B is significantly worse than A (``agentsctl eval compare`` exits 1 then)."""
        return self.verdict == WORSE

    def describe(self) -> str:
        """The comparison in a few lines of text."""
        lines = [f"A  {self.a.describe()}", f"B  {self.b.describe()}",
                 f"difference {self.difference * 100:+.1f} points, Fisher exact p = {self.p_value:.4g} "
                 f"(alpha {self.alpha:g}): B is {self.verdict_text()}"]
        if not self.same_seeds:
            lines.append("note: the two runs did not use the same seeds")
        return "\n".join(lines)

    def verdict_text(self) -> str:
        """The verdict as a phrase: ``worse than A``, ``better than A``, ``not significantly different from A``."""
        if self.verdict == NO_DIFFERENCE:
            return "not significantly different from A"
        return f"{self.verdict} than A"


def summarize_run(results: EvaluationResults, confidence: float = 0.95) -> RunSummary:
    """``results``' success count and rate with its Wilson interval at ``confidence``."""
    low, high = wilson_interval(results.successes, results.n, confidence)
    return RunSummary(name=results.info.name, out_dir=results.out_dir, n=results.n, successes=results.successes,
                      rate=results.success_rate, low=low, high=high, confidence=confidence)


def _as_results(run: str | Path | EvaluationResults) -> EvaluationResults:
    return run if isinstance(run, EvaluationResults) else load_results(run)


def compare_runs(dir_a: str | Path | EvaluationResults, dir_b: str | Path | EvaluationResults,
                 alpha: float = 0.05) -> Comparison:
    """Compare evaluation B (the candidate) with A (the reference): see the module's docstring.

    ``dir_a`` / ``dir_b`` are output directories (or results already loaded).
    """
    if isinstance(alpha, bool) or not isinstance(alpha, int | float) or not 0.0 < alpha < 1.0 \
            or not math.isfinite(alpha):
        raise ValueError(f"alpha must be between 0 and 1 (exclusive), got {alpha!r}")
    a, b = _as_results(dir_a), _as_results(dir_b)
    sa, sb = summarize_run(a), summarize_run(b)
    p_value = compare_success(sa.successes, sa.n, sb.successes, sb.n)
    verdict = NO_DIFFERENCE
    if p_value < alpha and sb.rate != sa.rate:
        verdict = BETTER if sb.rate > sa.rate else WORSE
    outcome_a: dict[int, bool] = {}
    for episode in a.episodes:
        outcome_a.setdefault(episode.seed, episode.success)
    outcome_b: dict[int, bool] = {}
    for episode in b.episodes:
        outcome_b.setdefault(episode.seed, episode.success)
    flipped = tuple((seed, outcome_a[seed], outcome_b[seed]) for seed in outcome_a
                    if seed in outcome_b and outcome_a[seed] != outcome_b[seed])
    same = sorted(e.seed for e in a.episodes) == sorted(e.seed for e in b.episodes)
    return Comparison(a=sa, b=sb, p_value=p_value, alpha=float(alpha), verdict=verdict, same_seeds=same,
                      flipped=flipped)
