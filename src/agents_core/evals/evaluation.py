"""``Evaluation``: what is judged, on which task, how often, and by which rule.

An evaluation is a world (a :class:`~agents_core.sim.GymWorld`, whose ``success`` rule says when
an episode succeeds), a recipe (the agent's components), a seeded initial-state distribution
(episode *i* resets the environment with ``seeds[i]``, by default ``seed + i``) and limits (steps
and wall time per episode). Both the world and the recipe are *factories* (functions returning
new components), so every run builds fresh ones::

    Evaluation(name="reacher-expert",
               world=lambda: GymWorld("Reacher-v5", success=reacher_success()),
               recipe=lambda: [ReacherExpert()],
               episodes=20, seed=1000, max_steps=50)

:func:`agents_core.evals.run_evaluation` runs it; ``agentsctl eval run file.py`` finds it in a
file (an ``Evaluation`` named ``evaluation``, or the one given by ``module:attr``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from attrs import define, field

from ..errors import ConfigError

if TYPE_CHECKING:
    from ..components.component_base import Component
    from ..sim.world import GymWorld

__all__ = ["Evaluation"]


def _positive_or_none(instance: Any, attribute: Any, value: Any) -> None:
    if value is not None and (isinstance(value, bool) or not isinstance(value, int | float) or not value > 0):
        raise ConfigError(f"Evaluation.{attribute.name}: expected a number > 0 or None, got {value!r}")


def _episodes(instance: Any, attribute: Any, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ConfigError(f"Evaluation.episodes: expected an int >= 1, got {value!r}")


def _seeds(value: Sequence[int] | None) -> tuple[int, ...] | None:
    return None if value is None else tuple(int(s) for s in value)


@define(kw_only=True)
class Evaluation:
    """A world, a recipe, seeds, limits (see the module docs).

    :param name: names the evaluation (and its report).
    :param world: makes the world component.
    :param recipe: makes the agent's components.
    :param episodes: how many episodes to run.
    :param seed: episode *i* uses ``seed + i`` (unless ``seeds`` is given).
    :param seeds: the reset seed of each episode, explicitly.
    :param max_steps: steps an episode may take (None: the environment's own limit).
    :param max_wall_s: seconds an episode may take.
    :param recipe_name: what drove the world, in words (default: the recipe's component types).
    """

    name: str
    world: Callable[[], GymWorld]
    recipe: Callable[[], Sequence[Component]]
    episodes: int = field(default=20, validator=_episodes)
    seed: int = 0
    seeds: tuple[int, ...] | None = field(default=None, converter=_seeds)
    max_steps: int | None = field(default=None, validator=_positive_or_none)
    max_wall_s: float | None = field(default=None, validator=_positive_or_none)
    recipe_name: str = ""

    def seed_list(self, episodes: int | None = None, seed: int | None = None) -> list[int]:
        """The reset seeds of the episodes to run (``episodes`` / ``seed`` override the evaluation's)."""
        count = self.episodes if episodes is None else episodes
        if isinstance(count, bool) or not isinstance(count, int) or count < 1:
            raise ConfigError(f"evaluation {self.name!r}: episodes must be an int >= 1, got {count!r}")
        if self.seeds is not None and seed is None:
            if count > len(self.seeds):
                raise ConfigError(f"evaluation {self.name!r}: {count} episodes asked, {len(self.seeds)} seeds given")
            return list(self.seeds[:count])
        first = self.seed if seed is None else int(seed)
        return [first + i for i in range(count)]
