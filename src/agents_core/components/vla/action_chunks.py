"""The queue of actions a chunking policy has predicted, with overlapping chunks aggregated.

A policy answers an observation taken at control step *t* with actions for steps *t, t+1, ...*.
The next observation is sent before those are all played, so chunks overlap: a step may get an
action from an older chunk and a newer one. :class:`ActionChunkQueue` keeps one action per future
step; an incoming action for a step already queued is combined with the queued one by the
aggregation function ``f(old, new)``; actions for steps already played are dropped.

Built-in aggregation functions, by name (the names LeRobot's robot client uses):
``"latest_only"`` (the newer chunk wins), ``"average"``, ``"weighted_average"`` (0.3 old + 0.7
new) and ``"conservative"`` (0.7 old + 0.3 new). Any callable ``f(old, new) -> array`` works too.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from ...errors import ConfigError

__all__ = ["AGGREGATION_FUNCTIONS", "ActionChunkQueue", "AggregationFunction", "aggregation_function"]

Vector = npt.NDArray[np.float64]
#: ``f(queued, incoming) -> action`` for one control step.
AggregationFunction = Callable[[Vector, Vector], Vector]

AGGREGATION_FUNCTIONS: dict[str, AggregationFunction] = {
    "latest_only": lambda old, new: new,
    "average": lambda old, new: 0.5 * old + 0.5 * new,
    "weighted_average": lambda old, new: 0.3 * old + 0.7 * new,
    "conservative": lambda old, new: 0.7 * old + 0.3 * new,
}


def aggregation_function(spec: str | AggregationFunction) -> AggregationFunction:
    """A built-in aggregation function by name, or ``spec`` itself when it is callable."""
    if callable(spec):
        return spec
    try:
        return AGGREGATION_FUNCTIONS[spec]
    except (KeyError, TypeError):
        raise ConfigError(f"unknown action aggregation function {spec!r}; use one of "
                          f"{sorted(AGGREGATION_FUNCTIONS)} or a callable f(old, new)") from None


class ActionChunkQueue:
    """Future actions by control step; thread-safe (a policy thread adds, a control loop pops).

    :param aggregate: how an incoming action is combined with one already queued for its step.
    :param max_actions: the most steps kept (a bound on what a policy can make us store); the
        furthest ones beyond it are dropped.
    """

    def __init__(self, aggregate: str | AggregationFunction = "latest_only", max_actions: int = 10_000) -> None:
        self._aggregate = aggregation_function(aggregate)
        self._max = max_actions
        self._lock = threading.Lock()
        self._actions: dict[int, Vector] = {}
        self._last_played = -1
        self.aggregated = 0
        self.dropped_late = 0

    def __len__(self) -> int:
        with self._lock:
            return len(self._actions)

    @property
    def last_played(self) -> int:
        """The step of the last action popped (-1 before the first)."""
        return self._last_played

    def add_chunk(self, first_step: int, chunk: Any) -> int:
        """Queue ``chunk`` (rows for steps ``first_step``, ``first_step + 1``, ...); returns how many were queued."""
        rows = np.asarray(chunk, dtype=np.float64)
        if rows.ndim != 2:
            raise ConfigError(f"an action chunk must be 2-D (n_actions, action_dim), got shape {rows.shape}")
        queued = 0
        with self._lock:
            for i, row in enumerate(rows):
                step = first_step + i
                if step <= self._last_played:
                    self.dropped_late += 1
                    continue
                old = self._actions.get(step)
                if old is not None:
                    self._actions[step] = np.asarray(self._aggregate(old, row.copy()), dtype=np.float64)
                    self.aggregated += 1
                else:
                    self._actions[step] = row.copy()
                queued += 1
            while len(self._actions) > self._max:
                del self._actions[max(self._actions)]
        return queued

    def pop_next(self) -> tuple[int, Vector] | None:
        """The earliest queued action and its step (None when empty); older steps cannot be queued after it."""
        with self._lock:
            if not self._actions:
                return None
            step = min(self._actions)
            self._last_played = step
            return step, self._actions.pop(step)

    def clear(self, last_played: int = -1) -> None:
        """Forget every queued action; steps up to ``last_played`` count as played."""
        with self._lock:
            self._actions.clear()
            self._last_played = last_played
            self.aggregated = 0
            self.dropped_late = 0
