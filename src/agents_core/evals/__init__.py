"""Evaluations: run an agent in a world over many seeded episodes and score it.

- :class:`Evaluation` (:mod:`.evaluation`): a world, a recipe, seeds, a success rule (the world's),
  limits.
- :func:`run_evaluation` (:mod:`.runner`): runs it on a transport and writes the results directory
  (``evaluation.json``, ``results.jsonl``, ``frames/``, ``report.html``); ``agentsctl eval run``.
- :class:`EpisodeHooks`: called around each episode (recorders).
- Reading results (:mod:`.results`), the statistics (:mod:`.stats`), the HTML report
  (:mod:`.report`), comparing two evaluations (:mod:`.compare`), the pytest helper (:mod:`.expect`)
  and the progress line (:mod:`.progress`).

Each name is imported from its module on first use: reading results does not load the launcher.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_facade

if TYPE_CHECKING:
    from .compare import Comparison, RunSummary, compare_runs
    from .evaluation import Evaluation
    from .expect import expect_success_rate
    from .progress import EpisodeProgress
    from .report import write_comparison_report, write_report
    from .results import EpisodeResult, EvaluationInfo, EvaluationResults, ResultsError, ResultsLimits, load_results
    from .runner import EpisodeHooks, EvaluationRun, run_evaluation
    from .stats import MeanInterval, compare_success, mean_interval, wilson_interval
else:
    __getattr__, __dir__ = lazy_facade(__name__)

__all__ = [
    "Comparison",
    "EpisodeHooks",
    "EpisodeProgress",
    "EpisodeResult",
    "Evaluation",
    "EvaluationInfo",
    "EvaluationResults",
    "EvaluationRun",
    "MeanInterval",
    "ResultsError",
    "ResultsLimits",
    "RunSummary",
    "compare_runs",
    "compare_success",
    "expect_success_rate",
    "load_results",
    "mean_interval",
    "run_evaluation",
    "wilson_interval",
    "write_comparison_report",
    "write_report",
]
