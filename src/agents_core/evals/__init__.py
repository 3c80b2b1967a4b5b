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

from ..support.lazy import lazy_facade

if TYPE_CHECKING:
    from .compare import Comparison as Comparison
    from .compare import RunSummary as RunSummary
    from .compare import compare_runs as compare_runs
    from .evaluation import Evaluation as Evaluation
    from .expect import expect_success_rate as expect_success_rate
    from .progress import EpisodeProgress as EpisodeProgress
    from .report import write_comparison_report as write_comparison_report
    from .report import write_report as write_report
    from .results import EpisodeResult as EpisodeResult
    from .results import EvaluationInfo as EvaluationInfo
    from .results import EvaluationResults as EvaluationResults
    from .results import ResultsError as ResultsError
    from .results import ResultsLimits as ResultsLimits
    from .results import load_results as load_results
    from .runner import EpisodeHooks as EpisodeHooks
    from .runner import EvaluationRun as EvaluationRun
    from .runner import run_evaluation as run_evaluation
    from .stats import MeanInterval as MeanInterval
    from .stats import compare_success as compare_success
    from .stats import mean_interval as mean_interval
    from .stats import wilson_interval as wilson_interval
else:
    __getattr__, __dir__ = lazy_facade(__name__)
