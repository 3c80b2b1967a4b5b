"""A small Gymnasium reaching task run as a real-time world on a transport, for the closed-loop LeRobot test.

``ToyReach`` (a ``gymnasium.Env``): two joints in [-1, 1] move towards the commanded position, at most
``MAX_STEP`` a step; the target is drawn from the seed; the camera (32 x 32 RGB) shows the target and
the arm's tip. Success (the rule of this test): both joints within ``TOLERANCE`` of the target at the
episode's end.

:class:`RealTimeWorld` steps it at ``rate`` Hz whatever the agent does, as a robot would: each tick
applies the latest JointState command, steps, and publishes the JointState and the camera frame. Once
sim's world component is merged (``agents_core.sim``), the lead may swap it in; the topics are the same.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import gymnasium as gym
import numpy as np

from agents_core import Topic
from agents_core.messages import ImageMsg, JointStateMsg

JOINTS = ["shoulder", "elbow"]
STATE = Topic("joint_states", "JointState")
CAMERA = Topic("top", "Image")
COMMANDS = Topic("joint_commands", "JointState")
MAX_STEP = 0.1
TOLERANCE = 0.1
SIDE = 32


class ToyReach(gym.Env):  # type: ignore[misc]
    """Reach a seeded target in joint space (see the module docstring)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}  # noqa: RUF012 - gymnasium's convention

    def __init__(self) -> None:
        self.observation_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float64)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float64)
        self.q = np.zeros(2)
        self.target = np.zeros(2)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        super().reset(seed=seed)
        self.q = np.zeros(2)
        self.target = self.np_random.uniform(-0.8, 0.8, 2)
        return self.q.copy(), {"target": self.target.copy()}

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        wanted = np.clip(np.asarray(action, np.float64), -1.0, 1.0)
        self.q = np.clip(self.q + np.clip(wanted - self.q, -MAX_STEP, MAX_STEP), -1.0, 1.0)
        distance = float(np.abs(self.q - self.target).max())
        return self.q.copy(), -distance, False, False, {"target": self.target.copy()}

    def render(self) -> np.ndarray:
        image = np.full((SIDE, SIDE, 3), 40, np.uint8)
        for (x, y), colour in ((self.target, (250, 60, 60)), (self.q, (60, 250, 60))):
            col, row = int((x + 1) / 2 * (SIDE - 4)), int((y + 1) / 2 * (SIDE - 4))
            image[row:row + 4, col:col + 4] = colour
        return image

    def success(self) -> bool:
        return bool(np.abs(self.q - self.target).max() < TOLERANCE)


class ToyReachDict(ToyReach):
    """``ToyReach`` as the framework's Gymnasium world reads one: ``{"agent_pos": q}`` observations,
    ``info["is_success"]`` (the world's default success rule), ``render_mode`` taken. Registered as
    ``ENV_ID`` by :func:`register`."""

    def __init__(self, render_mode: str | None = "rgb_array") -> None:
        super().__init__()
        self.render_mode = render_mode
        self.observation_space = gym.spaces.Dict({"agent_pos": gym.spaces.Box(-1.0, 1.0, (2,), np.float64)})

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        q, info = super().reset(seed=seed, options=options)
        return {"agent_pos": q}, {**info, "is_success": self.success()}

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        q, reward, terminated, truncated, info = super().step(action)
        return {"agent_pos": q}, reward, terminated, truncated, {**info, "is_success": self.success()}


ENV_ID = "AgentsToyReach-v0"


def register() -> str:
    """Register :class:`ToyReachDict` with Gymnasium (once); returns its id."""
    if ENV_ID not in gym.registry:
        gym.register(ENV_ID, entry_point="tests.lerobot.toy_world:ToyReachDict", max_episode_steps=200)
    return ENV_ID


def target_of(env: Any) -> np.ndarray:
    """The privileged state a scripted expert gets (GymWorld appends it to the observation vector)."""
    return np.asarray(env.unwrapped.target, np.float64)


class RealTimeWorld:
    """``ToyReach`` stepped at ``rate`` Hz on ``transport`` (see the module docstring)."""

    def __init__(self, transport: Any, rate: float = 20.0) -> None:
        self.env = ToyReach()
        self.rate = rate
        self._state = transport.create_publisher(STATE)
        self._camera = transport.create_publisher(CAMERA)
        self._command: np.ndarray | None = None
        self._lock = threading.Lock()
        self._commands = transport.create_subscription(COMMANDS, self._on_command)
        self.commands_received = 0
        self.steps = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _on_command(self, value: Any) -> None:
        positions = dict(zip(value.name, np.asarray(value.position, np.float64), strict=False))
        if all(j in positions and np.isfinite(positions[j]) for j in JOINTS):
            with self._lock:
                self._command = np.array([positions[j] for j in JOINTS])
                self.commands_received += 1

    def reset(self, seed: int) -> np.ndarray:
        """Stop stepping, reset the env with ``seed``, publish the first observation, step again."""
        self.stop()
        _, info = self.env.reset(seed=seed)
        with self._lock:
            self._command = None
        self.steps = 0
        self._publish()
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="toy-world", daemon=True)
        self._thread.start()
        return np.asarray(info["target"])

    def _publish(self) -> None:
        self._state.publish(JointStateMsg(name=JOINTS, position=self.env.q.copy()))
        self._camera.publish(ImageMsg.from_array(self.env.render()))

    def _run(self) -> None:
        period = 1.0 / self.rate
        next_tick = time.monotonic()
        while not self._stop.is_set():
            next_tick += period
            with self._lock:
                command = self._command
            self.env.step(self.env.q if command is None else command)
            self.steps += 1
            self._publish()
            self._stop.wait(max(0.0, next_tick - time.monotonic()))

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
            self._thread = None

    def close(self) -> None:
        self.stop()
        self._commands.close()
