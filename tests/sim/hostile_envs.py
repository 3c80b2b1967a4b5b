"""Small Gymnasium environments that misbehave on purpose, chosen by the reset seed (for the world's tests).

``tests.sim.hostile_envs:Hostile-v0``: a 3-number observation, a 1-number action; ``info["is_success"]``
from step 5 on when the action is positive; 10 steps an episode (truncated). At step 3 the seed decides:
1 raises, 2 hangs (sleeps 30 s), 3 returns NaN, 4 kills its process; others behave.
"""

from __future__ import annotations

import os
import time
from typing import Any, ClassVar

import gymnasium
import numpy as np
from gymnasium import spaces

__all__ = ["ENV_ID", "Hostile"]

ENV_ID = "tests.sim.hostile_envs:Hostile-v0"
RAISES, HANGS, NAN, DIES = 1, 2, 3, 4


class Hostile(gymnasium.Env[np.ndarray, np.ndarray]):
    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(self, render_mode: str | None = None, width: int = 16, height: int = 12) -> None:
        self.observation_space = spaces.Box(-10.0, 10.0, shape=(3,), dtype=np.float64)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        self.render_mode, self.size = render_mode, (height, width)
        self.mode, self.t = 0, 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self.mode, self.t = int(seed or 0), 0
        return np.array([0.0, 0.0, float(self.mode)]), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        self.t += 1
        if self.t == 3:
            if self.mode == RAISES:
                raise RuntimeError("the simulator exploded")
            if self.mode == HANGS:
                time.sleep(30)
            if self.mode == DIES:
                os._exit(3)
        value = float(np.asarray(action).reshape(-1)[0])
        observation = np.array([float(self.t), value, float(self.mode)])
        if self.mode == NAN and self.t == 3:
            observation[1] = np.nan
        info = {"is_success": self.t >= 5 and value > 0}
        return observation, value, False, self.t >= 10, info

    def render(self) -> np.ndarray:
        frame = np.zeros((*self.size, 3), np.uint8)
        frame[:, : self.t % self.size[1]] = 200
        return frame


gymnasium.register(id="Hostile-v0", entry_point=Hostile, max_episode_steps=None, disable_env_checker=True)
