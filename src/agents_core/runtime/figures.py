"""``StepFigures``: what ``agentsctl top`` shows of a component, kept by its runtime at a few ns per step.

The runtime adds each step's duration (:meth:`StepFigures.add`, a deque append); the figures are
computed only when the status is published (at ``config.status_rate``, at most 10 Hz, and on a
health change) and travel as compact JSON in the status message's ``stats`` field
(:class:`~agents_core.messages.ComponentStatusMsg`): steps, step rate, p50 / p99 step time, the
last model call's latency, drops, restarts, this process's CPU share and RSS, and its pid.
"""

from __future__ import annotations

import collections
import json
import os
import time
from collections.abc import Mapping
from typing import Any, Protocol

from ..telemetry.process import CpuMeter, process_figures
from .worker import WorkerStatistics

__all__ = ["MAX_STATS_BYTES", "STATS_FIELDS", "StepFigures", "parse_stats", "percentile"]

#: The keys of the ``stats`` document, in the order ``agentsctl top`` shows them.
STATS_FIELDS = ("steps", "rate_hz", "p50_ms", "p99_ms", "model_ms", "drops", "restarts", "cpu", "rss_mb", "pid")
#: Longest ``stats`` document read from a status (it comes from the network).
MAX_STATS_BYTES = 4096
#: Step durations kept for the percentiles (the most recent ones).
WINDOW = 512
#: The step rate is computed over at least this long (faster reports reuse the last rate).
MIN_RATE_WINDOW_S = 0.5


class _Counted(Protocol):
    """What the figures read from a component's runtime."""

    def worker_statistics(self) -> WorkerStatistics: ...

    def input_statistics(self) -> Mapping[str, Any]: ...

    def model_latency_ms(self) -> float | None: ...


def parse_stats(text: str) -> dict[str, float]:
    """The numbers of a ``stats`` document (``cpu`` as ``cpu_pct``); {} for one empty, too long or not an object."""
    if not text or len(text) > MAX_STATS_BYTES:
        return {}
    try:
        doc = json.loads(text)
    except (ValueError, RecursionError):
        return {}
    if not isinstance(doc, dict):
        return {}
    figures = {k: doc[k] for k in STATS_FIELDS
               if isinstance(doc.get(k), int | float) and not isinstance(doc[k], bool)}
    if "cpu" in figures:
        figures["cpu_pct"] = round(figures.pop("cpu") * 100.0, 1)
    return figures


def percentile(sorted_values: list[float], q: float) -> float:
    """The ``q`` quantile (0..1) of sorted values, nearest rank; 0.0 for none."""
    if not sorted_values:
        return 0.0
    rank = min(len(sorted_values) - 1, max(0, round(q * (len(sorted_values) - 1))))
    return sorted_values[rank]


class StepFigures:
    """Recent step durations and the counters behind the ``stats`` document of one component."""

    def __init__(self) -> None:
        self.durations: collections.deque[float] = collections.deque(maxlen=WINDOW)
        self.add = self.durations.append
        self.activations = 0
        self._rate = 0.0
        self._last = (time.monotonic(), 0)
        self._cpu = CpuMeter()

    def document(self, runtime: _Counted) -> dict[str, Any]:
        """The figures now, as the ``stats`` document (see the module docstring)."""
        now = time.monotonic()
        steps = runtime.worker_statistics().executed
        then, before = self._last
        if now - then >= MIN_RATE_WINDOW_S:
            self._rate = max(0, steps - before) / (now - then)
            self._last = (now, steps)
        ordered = sorted(self.durations)
        drops = runtime.worker_statistics().dropped + sum(s.dropped for s in runtime.input_statistics().values())
        process = process_figures()
        return {"steps": steps, "rate_hz": round(self._rate, 2), "p50_ms": round(percentile(ordered, 0.5) * 1e3, 3),
                "p99_ms": round(percentile(ordered, 0.99) * 1e3, 3), "model_ms": runtime.model_latency_ms(),
                "drops": drops, "restarts": max(0, self.activations - 1), "cpu": round(self._cpu.share(process), 3),
                "rss_mb": round(process.rss_bytes / 2**20, 1), "pid": os.getpid()}

    def text(self, runtime: _Counted) -> str:
        """:meth:`document` as compact JSON."""
        return json.dumps(self.document(runtime), separators=(",", ":"))
