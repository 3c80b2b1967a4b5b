"""Success rules: when an episode of a world counts as a success.

A rule is called after every step with the step's observation and ``info`` and answers whether the
task is done in that state. ``at_end=True`` rules judge the episode by its last state (the
Reacher's fingertip must *be* at the target when time runs out); the others by the first state
that satisfies them, and with ``stop_on_success`` that state ends the episode. Rules are plain
picklable objects, so a world in a process of its own gets the same one.

- :class:`EnvSuccess`: the environment's own verdict, ``info["is_success"]`` (Push-T, ALOHA...).
- :class:`DistanceBelow`: a distance read from the observation vector is below a threshold.
- :class:`Predicate`: any module-level function ``(observation, info) -> bool``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np
from attrs import define, field

__all__ = ["DistanceBelow", "EnvSuccess", "Predicate", "SuccessRule", "reacher_success"]


@runtime_checkable
class SuccessRule(Protocol):
    """What a world asks after each step: is the task done in this state?"""

    @property
    def at_end(self) -> bool:
        """Judge the episode by its final state (True) or by the first state that succeeds (False)."""
        ...

    @property
    def stop_on_success(self) -> bool:
        """End the episode at the first success (ignored when ``at_end``)."""
        ...

    def __call__(self, observation: Any, info: Mapping[str, Any]) -> bool: ...

    def describe(self) -> str:
        """The rule in words (``success_rule`` of evaluation.json)."""
        ...


@define(frozen=True)
class EnvSuccess:
    """The environment's own verdict: ``info[key]`` is true (default key ``"is_success"``)."""

    key: str = "is_success"
    at_end: bool = False
    stop_on_success: bool = True

    def __call__(self, observation: Any, info: Mapping[str, Any]) -> bool:
        return bool(info.get(self.key, False))

    def describe(self) -> str:
        return f"the environment's own rule (info[{self.key!r}])"


def _indices(value: Sequence[int]) -> tuple[int, ...]:
    return tuple(int(i) for i in value)


@define(frozen=True)
class DistanceBelow:
    """Success when the norm of ``observation[indices]`` is below ``threshold`` (by default at the end).

    :param indices: positions in the (flattened) observation vector of a difference vector.
    :param threshold: the distance, in the observation's units.
    :param key: for a dict observation, the entry holding the vector.
    """

    indices: tuple[int, ...] = field(converter=_indices)
    threshold: float = 0.02
    key: str | None = None
    at_end: bool = True
    stop_on_success: bool = False
    name: str = "distance"

    def distance(self, observation: Any) -> float:
        """The distance in ``observation``."""
        vector = observation[self.key] if self.key is not None else observation
        flat = np.asarray(vector, dtype=np.float64).reshape(-1)
        return float(np.linalg.norm(flat[list(self.indices)]))

    def __call__(self, observation: Any, info: Mapping[str, Any]) -> bool:
        return self.distance(observation) < self.threshold

    def describe(self) -> str:
        when = "at the end of the episode" if self.at_end else "at any step"
        return f"{self.name} (|observation[{', '.join(map(str, self.indices))}]|) below {self.threshold:g} {when}"


@define(frozen=True)
class Predicate:
    """Success when ``func(observation, info)`` is true; ``func`` must be a module-level function (picklable)."""

    func: Callable[[Any, Mapping[str, Any]], bool]
    description: str = ""
    at_end: bool = False
    stop_on_success: bool = True

    def __call__(self, observation: Any, info: Mapping[str, Any]) -> bool:
        return bool(self.func(observation, info))

    def describe(self) -> str:
        return self.description or getattr(self.func, "__qualname__", repr(self.func))


def reacher_success(threshold: float = 0.02) -> DistanceBelow:
    """Reacher-v5: the fingertip within ``threshold`` m of the target at the end of the episode.

    Reacher-v5's observation ends with the fingertip-minus-target vector (x, y) at indices 8 and 9.
    """
    return DistanceBelow(indices=(8, 9), threshold=threshold, name="fingertip to target")
