"""Evaluations: run an agent in a world over many seeded episodes and score it.

- :class:`Evaluation` (:mod:`.evaluation`): a world, a recipe, seeds, a success rule (the world's),
  limits.
- :func:`run_evaluation` (:mod:`.runner`): runs it on a transport and writes the results directory
  (``evaluation.json``, ``results.jsonl``, ``frames/``, ``report.html``); ``agentsctl eval run``.
- :class:`EpisodeHooks`: called around each episode (recorders).

The statistics, the HTML report, comparisons and the pytest helper are in :mod:`.stats`,
:mod:`.report`, :mod:`.compare` and :mod:`.expect`.
"""

from __future__ import annotations

from .evaluation import Evaluation
from .runner import EpisodeHooks, EvaluationRun, run_evaluation

__all__ = ["EpisodeHooks", "Evaluation", "EvaluationRun", "run_evaluation"]
