"""Simulated worlds: any Gymnasium environment as a component (the ``sim`` extra).

- :class:`GymWorld` / :class:`GymWorldConfig` (:mod:`.world`): the environment's observations,
  camera frames, joints, reward and episode ends out as topics, its action in; episodes as a
  component action, in lock-step or in real time.
- :class:`RandomAgent` (:mod:`.agents`): the floor an agent must beat.
- Success rules (:mod:`.rules`): :class:`EnvSuccess`, :class:`DistanceBelow`, :class:`Predicate`,
  :func:`reacher_success`.
- :mod:`.env_host`: one environment on a thread of its own, every call bounded in time.

Importing this package imports neither Gymnasium nor MuJoCo; a world makes its environment when
it is configured.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..support.lazy import lazy_facade
from .agents import RandomAgent as RandomAgent
from .rules import DistanceBelow as DistanceBelow
from .rules import EnvSuccess as EnvSuccess
from .rules import Predicate as Predicate
from .rules import SuccessRule as SuccessRule
from .rules import reacher_success as reacher_success
from .world import GymWorld as GymWorld
from .world import GymWorldConfig as GymWorldConfig

if not TYPE_CHECKING:
    __getattr__, __dir__ = lazy_facade(__name__, own=("action_space_bounds",))


def action_space_bounds(env_id: str, env_kwargs: dict[str, object] | None = None) -> tuple[list[float], list[float]]:
    """The (low, high) bounds of an environment's Box action space (makes the environment once, closes it)."""
    from .env_host import make_env  # noqa: PLC0415

    env = make_env(env_id, dict(env_kwargs or {}), None)
    try:
        space = env.action_space
        return [float(v) for v in space.low.reshape(-1)], [float(v) for v in space.high.reshape(-1)]
    finally:
        env.close()
