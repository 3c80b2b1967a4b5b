"""An evaluation as a pytest assertion: fail when the success rate is under a threshold.

::

    from agents_core.evals.expect import expect_success_rate

    def test_reacher_expert_succeeds():
        out = run_my_evaluation(episodes=20)          # an output directory (or loaded results)
        expect_success_rate(out, at_least=0.8)

The :class:`AssertionError` says what pytest's own diff cannot: the rate, its 95 % interval, the
number of episodes, how they ended and which seeds failed (to rerun them one by one).
"""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

from .results import EvaluationResults, load_results
from .stats import wilson_interval

__all__ = ["expect_success_rate", "success_summary"]

#: At most this many failed seeds are listed in the message.
_MAX_SEEDS_SHOWN = 30


def success_summary(results: EvaluationResults, confidence: float = 0.95) -> str:
    """``'reacher-expert': 15/20 succeeded = 75.0 % (95 % interval 53.1-88.8 %); ended: success 15, step_limit 5``."""
    low, high = wilson_interval(results.successes, results.n, confidence)
    ended = ", ".join(f"{word} {count}" for word, count in Counter(e.ended for e in results.episodes).most_common())
    text = (f"{results.info.name!r}: {results.successes}/{results.n} succeeded = {results.success_rate * 100:.1f} % "
            f"({confidence * 100:g} % interval {low * 100:.1f}-{high * 100:.1f} %)")
    if ended:
        text += f"; ended: {ended}"
    if not results.complete:
        text += f"; the run did not finish ({results.n} of {results.info.episodes} episodes)"
    return text


def expect_success_rate(results_or_dir: EvaluationResults | str | Path, at_least: float, *,
                        min_episodes: int = 1) -> EvaluationResults:
    """Fail (:class:`AssertionError`) unless the success rate is at least ``at_least`` (0-1) over ``min_episodes``+.

    Returns the results, for further checks. The rate compared is the measured one (successes / episodes);
    the message gives its interval too, to show how much the threshold could be luck.
    """
    if isinstance(at_least, bool) or not isinstance(at_least, int | float) or not math.isfinite(at_least) \
            or not 0.0 <= at_least <= 1.0:
        raise ValueError(f"at_least is a success rate between 0 and 1, got {at_least!r}")
    results = results_or_dir if isinstance(results_or_dir, EvaluationResults) else load_results(results_or_dir)
    summary = success_summary(results)
    if results.n < max(1, min_episodes):
        raise AssertionError(f"only {results.n} episode(s) finished, fewer than the {max(1, min_episodes)} "
                             f"needed to judge a success rate: {summary}")
    if results.success_rate < at_least:
        failed = results.failed_seeds
        shown = ", ".join(str(s) for s in failed[:_MAX_SEEDS_SHOWN])
        if len(failed) > _MAX_SEEDS_SHOWN:
            shown += f", ... ({len(failed) - _MAX_SEEDS_SHOWN} more)"
        reasons = sorted({e.reason for e in results.episodes if e.reason})[:3]
        message = (f"success rate {results.success_rate * 100:.1f} % is under {at_least * 100:g} %: {summary}; "
                   f"failed seeds: {shown}")
        if reasons:
            message += f"; reasons given: {'; '.join(r[:200] for r in reasons)}"
        message += f" (results in {results.out_dir})"
        raise AssertionError(message)
    return results
