"""``RandomAgent``: the floor every evaluation should beat — a uniformly random action per observation.

The action is drawn from a generator seeded by the agent's ``seed`` and the observation's bytes,
so the same observation always gets the same action: in lock-step the same seeds give the same
episodes, however many episodes ran before.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..components.component_base import Component
from ..errors import ConfigError
from ..topics import Topic

__all__ = ["RandomAgent"]


class RandomAgent(Component):
    """Answers each observation with a uniformly random action within ``[low, high]``.

    :param low: the action's lower bounds (one per action value).
    :param high: its upper bounds.
    :param observation_topic: the topic that triggers it (Float64MultiArray).
    :param action_topic: where it publishes its action (Float64MultiArray).
    :param seed: mixed into every draw.
    """

    def __init__(self, low: Sequence[float], high: Sequence[float], *, observation_topic: str = "observation",
                 action_topic: str = "action", seed: int = 0, component_name: str = "random_agent",
                 **kwargs: Any) -> None:
        self.low = np.asarray(low, dtype=np.float64).reshape(-1)
        self.high = np.asarray(high, dtype=np.float64).reshape(-1)
        if self.low.shape != self.high.shape or not np.all(np.isfinite(self.low)) \
                or not np.all(np.isfinite(self.high)) or np.any(self.low > self.high):
            raise ConfigError(f"component {component_name!r}: low and high must be finite bounds of one size "
                              f"with low <= high, got {self.low.tolist()} and {self.high.tolist()}")
        self.seed = int(seed)
        observation = Topic(observation_topic, "Float64MultiArray")
        super().__init__(inputs=[observation], outputs=[Topic(action_topic, "Float64MultiArray")],
                         trigger=observation, component_name=component_name, **kwargs)

    def act(self, observation: Any) -> np.ndarray[Any, np.dtype[np.float64]]:
        """The action for ``observation`` (the same one every time)."""
        data = np.ascontiguousarray(np.asarray(observation, dtype=np.float64)).tobytes()
        digest = hashlib.blake2b(data, digest_size=8, key=self.seed.to_bytes(8, "little", signed=True)).digest()
        rng = np.random.default_rng(int.from_bytes(digest, "little"))
        return rng.uniform(self.low, self.high)

    def _execution_step(self, **kwargs: Any) -> None:
        observation = next(iter(self.trig_callbacks.values())).get_output()
        if observation is None:
            return
        action = self.act(observation)
        for pub in self.publishers_dict.values():
            pub.publish(action)
