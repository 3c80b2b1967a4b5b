"""``GymWorld``: any Gymnasium environment as a component that speaks topics.

Each step the world publishes (names are constructor arguments; None leaves one out):

- ``camera`` (Image, rgb8): a frame per camera, ``render()`` at ``render_width`` x ``render_height``
  (160x120 by default) or an image entry of the observation (ALOHA's ``pixels/top``);
- ``joint_states`` (JointState): the hinge and slide joints of a MuJoCo model (positions and
  velocities), or the observation's ``agent_pos`` entry;
- ``reward`` (Float64), ``terminated`` and ``truncated`` (Bool);
- ``observation`` (Float64MultiArray): the observation's numbers, last (an agent triggered by it
  finds the other topics of the same step already sent).

and takes its action on ``action`` (Float64MultiArray, JointState or Twist, see
:mod:`agents_core.sim.convert`). An episode is a component action, :meth:`GymWorld.run_episode`
(``<world>/execute_method``, so a world in a process of its own runs episodes the same way), and
:meth:`GymWorld.reset` starts one by hand. Two clocks (``config.clock``):

- ``"lockstep"``: the world waits for the agent's action after each observation (up to
  ``action_timeout``; the observation is sent again every ``resend_interval`` meanwhile, for an
  agent whose subscription was not matched yet). Same seeds, same agent: same episodes.
- ``"realtime"``: the world steps at ``control_rate`` Hz whatever the agent does, as a robot
  would, with the newest action received (the previous one held; zeros before the first).

The environment lives on a thread of its own (:class:`~agents_core.sim.env_host.EnvHost`): an
environment that raises, hangs past ``step_timeout`` or returns NaN ends the episode with
``ended="error"`` and a reason, and the next episode gets a fresh environment if it hung.
"""

from __future__ import annotations

import contextlib
import json
import math
import queue
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np
from attrs import define, field

from .. import base_validators
from ..actions import component_action
from ..components.component_base import Component
from ..config import BaseComponentConfig
from ..errors import AlgorithmFailure, ConfigError
from ..messages import ImageMsg, JointStateMsg
from ..topics import Topic
from .convert import ACTION_TYPES, action_vector, find_nonfinite, image_at, mujoco_joints, observation_vector
from .env_host import EnvHost, EnvHung, make_env
from .rules import EnvSuccess, SuccessRule
from .thumbnails import Thumbnails

__all__ = ["GymWorld", "GymWorldConfig"]


def _optional_positive(instance: Any, attribute: Any, value: Any) -> None:
    if value is not None and (isinstance(value, bool) or not isinstance(value, int | float) or not value > 0):
        raise ConfigError(f"{type(instance).__name__}.{attribute.name}: expected a number > 0 or None, got {value!r}")


@define(kw_only=True)
class GymWorldConfig(BaseComponentConfig):
    """Settings of :class:`GymWorld`.

    :param clock: ``"lockstep"`` (wait for the agent each step: deterministic) or ``"realtime"``.
    :param control_rate: realtime steps per second (None: the environment's own rate, 1/dt).
    :param render_width: width of rendered camera frames.
    :param render_height: height of rendered camera frames.
    :param step_timeout: seconds one environment call (reset, step) may take before the episode ends as hung.
    :param action_timeout: lockstep: seconds to wait for the agent's action before the episode ends.
    :param resend_interval: lockstep: the observation is sent again after this long without an action.
    :param max_steps: steps an episode may take (None: until the environment ends it).
    :param thumbnails: frames of each episode kept as thumbnails (for reports).
    :param publish_final_observation: also publish the observation that ends an episode (an agent
        answering it sends an action no step takes).
    """

    clock: Literal["lockstep", "realtime"] = field(default="lockstep",
                                                   validator=base_validators.in_(["lockstep", "realtime"]))
    control_rate: float | None = field(default=None, validator=_optional_positive)
    render_width: int = field(default=160, validator=base_validators.in_range(8, 4096))
    render_height: int = field(default=120, validator=base_validators.in_range(8, 4096))
    step_timeout: float = field(default=30.0, validator=base_validators.in_range(0.01, 3600.0))
    action_timeout: float = field(default=10.0, validator=base_validators.in_range(0.01, 3600.0))
    resend_interval: float = field(default=1.0, validator=base_validators.in_range(0.01, 3600.0))
    max_steps: int | None = field(default=None, validator=_optional_positive)
    thumbnails: int = field(default=8, validator=base_validators.in_range(0, 64))
    publish_final_observation: bool = field(default=False)


class _EpisodeEnd(Exception):
    def __init__(self, ended: str, reason: str | None = None) -> None:
        super().__init__(ended)
        self.ended, self.reason = ended, reason


class GymWorld(Component):
    """A Gymnasium environment as a component (see the module docs).

    :param env_id: the Gymnasium id (``"Reacher-v5"``, ``"gym_pusht/PushT-v0"``, ...).
    :param env_kwargs: keyword arguments of ``gymnasium.make``.
    :param success: the success rule (default: the environment's own ``info["is_success"]``).
    :param cameras: Image topic name -> source: ``"render"`` or an observation path (``"pixels/top"``).
    :param joint_names: names for the joints of an ``agent_pos`` observation entry, and the order
        a JointState action's positions are taken in.
    :param action_type: ``"Float64MultiArray"``, ``"Float32MultiArray"``, ``"JointState"`` or ``"Twist"``.
    :param privileged_state: a module-level function ``(env) -> array`` whose numbers are appended to each
        observation vector (what a scripted expert may know and a policy may not: an object's pose).
    """

    config_class = GymWorldConfig

    def __init__(
        self,
        env_id: str,
        *,
        env_kwargs: Mapping[str, Any] | None = None,
        success: SuccessRule | None = None,
        observation_topic: str | None = "observation",
        action_topic: str = "action",
        action_type: str = "Float64MultiArray",
        cameras: Mapping[str, str] | None = None,
        joint_states_topic: str | None = "joint_states",
        joint_names: Sequence[str] | None = None,
        reward_topic: str | None = "reward",
        terminated_topic: str | None = "terminated",
        truncated_topic: str | None = "truncated",
        info_topic: str | None = None,
        privileged_state: Callable[[Any], Any] | None = None,
        config: GymWorldConfig | None = None,
        component_name: str = "world",
        **kwargs: Any,
    ) -> None:
        if action_type not in ACTION_TYPES:
            raise ConfigError(f"component {component_name!r}: action_type must be one of {list(ACTION_TYPES)}, "
                              f"got {action_type!r}")
        self.env_id = env_id
        self.env_kwargs = dict(env_kwargs or {})
        self.success_rule: SuccessRule = EnvSuccess() if success is None else success
        self.cameras = dict({"camera": "render"} if cameras is None else cameras)
        self.joint_names = list(joint_names) if joint_names else None
        self.privileged_state = privileged_state
        self._names = {"observation": observation_topic, "joint_states": joint_states_topic,
                       "reward": reward_topic, "terminated": terminated_topic, "truncated": truncated_topic,
                       "info": info_topic}
        types = {"observation": "Float64MultiArray", "joint_states": "JointState", "reward": "Float64",
                 "terminated": "Bool", "truncated": "Bool", "info": "String"}
        outputs = [Topic(name, "Image") for name in self.cameras]
        outputs += [Topic(name, types[key]) for key, name in self._names.items() if name]
        self.action_topic = Topic(action_topic, action_type)
        super().__init__(inputs=[self.action_topic], outputs=outputs, config=config, trigger=None,
                         component_name=component_name, run_type="Server", **kwargs)
        self.config: GymWorldConfig
        self._actions: queue.Queue[Any] = queue.Queue(maxsize=64)
        self._stop = threading.Event()
        self._host: EnvHost | None = None
        self._joints: list[tuple[str, int, int]] = []
        self._action_shape: tuple[int, ...] = ()
        self._step_dt: float | None = None
        self._last_observation: Any = None
        self.callbacks[action_topic].on_callback_execute(self._on_action)

    @classmethod
    def _server_capable(cls) -> bool:
        return True

    # -- the environment --------------------------------------------------------------------

    def _new_host(self) -> EnvHost:
        size = (self.config.render_width, self.config.render_height) if "render" in self.cameras.values() else None
        host = EnvHost(lambda: make_env(self.env_id, self.env_kwargs, size), name=self.env_id,
                       timeout=self.config.step_timeout)

        def describe(env: Any) -> tuple[list[tuple[str, int, int]], tuple[int, ...], float | None]:
            unwrapped = env.unwrapped
            if getattr(unwrapped, "control_hz", None):
                dt: float | None = 1.0 / float(unwrapped.control_hz)
            elif isinstance(getattr(unwrapped, "dt", None), int | float):
                dt = float(unwrapped.dt)
            else:
                fps = env.metadata.get("render_fps")
                dt = 1.0 / float(fps) if fps else None
            return mujoco_joints(env), tuple(env.action_space.shape or ()), dt

        self._joints, self._action_shape, self._step_dt = host.call(describe, "reading its spaces")
        return host

    def _host_now(self) -> EnvHost:
        if self._host is None or self._host.broken:
            self._host = self._new_host()
        return self._host

    def custom_on_configure(self) -> None:
        self._host_now()

    def custom_on_activate(self) -> None:
        self._stop.clear()

    def custom_on_deactivate(self) -> None:
        self._stop.set()

    def _close_host(self) -> None:
        host, self._host = self._host, None
        if host is not None:
            host.close()

    def custom_on_cleanup(self) -> None:
        self._close_host()

    def custom_on_shutdown(self) -> None:
        self._stop.set()
        self._close_host()

    @property
    def step_dt(self) -> float | None:
        """Simulated seconds per step (None when the environment does not say)."""
        return self._step_dt

    # -- topics -----------------------------------------------------------------------------

    def _on_action(self, value: Any) -> None:
        try:
            self._actions.put_nowait(value)
        except queue.Full:  # an agent far ahead of the world: the oldest action goes
            with contextlib.suppress(queue.Empty):
                self._actions.get_nowait()
            self._actions.put_nowait(value)

    def _drain_actions(self) -> Any:
        latest = None
        while True:
            try:
                latest = self._actions.get_nowait()
            except queue.Empty:
                return latest

    def _capture(self, env: Any, observation: Any) -> dict[str, Any]:
        """On the env thread: camera frames and joints for publishing."""
        frames: dict[str, Any] = {}
        for name, source in self.cameras.items():
            frame = env.render() if source == "render" else image_at(observation, source)
            if frame is not None:
                frames[name] = np.ascontiguousarray(frame)
        joints = None
        if self._joints:
            data = env.unwrapped.data
            joints = ([n for n, _, _ in self._joints], [float(data.qpos[q]) for _, q, _ in self._joints],
                      [float(data.qvel[v]) for _, _, v in self._joints])
        elif isinstance(observation, Mapping) and "agent_pos" in observation:
            position = np.asarray(observation["agent_pos"], dtype=np.float64).reshape(-1)
            names = self.joint_names or [f"joint{i}" for i in range(position.size)]
            if len(names) == position.size:
                joints = (list(names), position.tolist(), [])
        privileged = None
        if self.privileged_state is not None:
            privileged = np.asarray(self.privileged_state(env), dtype=np.float64).reshape(-1)
        return {"frames": frames, "joints": joints, "privileged": privileged}

    def _publish(self, key: str, value: Any) -> None:
        name = self._names.get(key)
        if name:
            self.publishers_dict[name].publish(value)

    def _publish_state(self, observation: Any, extras: dict[str, Any], *, reward: float | None = None,
                       terminated: bool = False, truncated: bool = False, info: Mapping[str, Any] | None = None,
                       observation_too: bool = True) -> None:
        for name, frame in extras["frames"].items():
            encoding = "rgb8" if frame.shape[2] == 3 else "mono8"
            self.publishers_dict[name].publish(ImageMsg(data=frame, encoding=encoding))
        if extras["joints"] is not None:
            names, position, velocity = extras["joints"]
            self._publish("joint_states", JointStateMsg(name=names, position=position, velocity=velocity))
        if reward is not None:
            self._publish("reward", float(reward))
            self._publish("terminated", bool(terminated))
            self._publish("truncated", bool(truncated))
        if info is not None and self._names["info"]:
            plain = {k: (v.item() if isinstance(v, np.generic) else v) for k, v in info.items()
                     if isinstance(v, bool | int | float | str | np.generic)}
            self._publish("info", json.dumps(plain, default=str))
        if observation_too:
            vector = observation_vector(observation)
            if extras["privileged"] is not None:
                vector = np.concatenate([vector, extras["privileged"]])
            self._publish("observation", vector)

    # -- episodes ---------------------------------------------------------------------------

    @component_action
    def reset(self, seed: int | None = None) -> dict[str, Any]:
        """Reset the environment (with ``seed``) and publish the first observation."""
        host = self._host_now()

        def do(env: Any) -> tuple[Any, dict[str, Any]]:
            observation, _info = env.reset(seed=seed)
            return observation, self._capture(env, observation)

        self._drain_actions()
        observation, extras = host.call(do, "reset")
        bad = find_nonfinite(observation)
        if bad is not None:
            raise AlgorithmFailure(f"world {self.component_name!r}: reset returned {bad}")
        self._last_observation = observation
        self._publish_state(observation, extras)
        return {"seed": seed, "observation": observation_vector(observation).tolist()}

    @component_action
    def stop_episode(self) -> bool:
        """Make a running episode end now (``ended="interrupted"``); returns True."""
        self._stop.set()
        return True

    @component_action
    def run_episode(self, seed: int, max_steps: int | None = None, max_wall_s: float | None = None,
                    frames_dir: str | None = None, frame_prefix: str = "") -> dict[str, Any]:
        """Run one episode from ``reset(seed)`` to its end; returns its results line (see agents_core.evals).

        ``frames_dir``: where to write its thumbnails (``<frame_prefix>_NN.jpg``); the line names them
        relative to that directory's parent.
        """
        self._stop.clear()
        limit = max_steps if max_steps is not None else self.config.max_steps
        start = time.monotonic()
        rewards: list[float] = []
        thumbs = Thumbnails(self.config.thumbnails)
        state: dict[str, Any] = {"success": False, "first": None, "ended": "error", "reason": None}
        try:
            self._episode(seed, limit, max_wall_s, start, rewards, thumbs, state)
        except _EpisodeEnd as end:
            state["ended"], state["reason"] = end.ended, end.reason
        success = bool(state["success"])
        first = state["first"] if success else None
        frames = thumbs.write(Path(frames_dir), frame_prefix) if frames_dir else []
        return {"seed": int(seed), "success": success, "reward_sum": float(math.fsum(rewards)), "steps": len(rewards),
                "time_to_success_s": (first * self._step_dt if first is not None and self._step_dt else None),
                "steps_to_success": first, "wall_s": time.monotonic() - start, "ended": state["ended"],
                "reason": state["reason"], "rewards": rewards, "frames": frames}

    def _call(self, host: EnvHost, func: Any, what: str) -> Any:
        try:
            return host.call(func, what)
        except EnvHung as exc:
            raise _EpisodeEnd("error", str(exc)) from None
        except Exception as exc:
            raise _EpisodeEnd("error", f"the environment raised in {what}: {type(exc).__name__}: {exc}") from None

    def _episode(self, seed: int, limit: int | None, max_wall_s: float | None, start: float,
                 rewards: list[float], thumbs: Thumbnails, state: dict[str, Any]) -> None:
        try:
            host = self._host_now()
        except Exception as exc:
            raise _EpisodeEnd("error", f"making the environment failed: {type(exc).__name__}: {exc}") from None

        def do_reset(env: Any) -> tuple[Any, Any, dict[str, Any]]:
            observation, info = env.reset(seed=int(seed))
            return observation, info, self._capture(env, observation)

        self._drain_actions()
        observation, info, extras = self._call(host, do_reset, "reset")
        self._check(observation, None)
        thumbs.add(extras["frames"])
        self._publish_state(observation, extras)
        realtime = self.config.clock == "realtime"
        rate = self.config.control_rate or (1.0 / self._step_dt if self._step_dt else 10.0)
        held: Any = np.zeros(self._action_shape)
        next_tick = time.monotonic()
        while True:
            if self._stop.is_set():
                raise _EpisodeEnd("interrupted", "the evaluation was stopped")
            if realtime:
                next_tick += 1.0 / rate
                self._stop.wait(max(0.0, next_tick - time.monotonic()))
                latest = self._drain_actions()
                if latest is not None:
                    held = self._to_action(latest)
                action = held
            else:
                action = self._to_action(self._await_action(observation, extras))

            def do_step(env: Any, action: Any = action) -> tuple[Any, ...]:
                result = env.step(action)
                return (*result, self._capture(env, result[0]))

            observation, reward, terminated, truncated, info, extras = self._call(host, do_step, "step")
            self._check(observation, reward)
            rewards.append(float(reward))
            thumbs.add(extras["frames"])
            self._judge(observation, info, len(rewards), state)
            ended = self._ended(state, terminated, truncated, len(rewards), limit, max_wall_s, start)
            final = ended is not None
            self._publish_state(observation, extras, reward=float(reward), terminated=bool(terminated),
                                truncated=bool(truncated), info=info,
                                observation_too=not final or self.config.publish_final_observation)
            if final:
                if self.success_rule.at_end:
                    state["success"] = state["first"] is not None
                raise _EpisodeEnd(str(ended))

    def _judge(self, observation: Any, info: Mapping[str, Any], steps: int, state: dict[str, Any]) -> None:
        rule = self.success_rule
        try:
            met = rule(observation, info)
        except Exception as exc:  # a rule that fails on this state ends the episode, with why
            raise _EpisodeEnd("error", f"the success rule raised: {type(exc).__name__}: {exc}") from None
        if met:
            if state["first"] is None:
                state["first"] = steps
            if not rule.at_end:
                state["success"] = True
        elif rule.at_end:
            state["first"] = None  # at_end: the first step of the final run of successes

    def _ended(self, state: dict[str, Any], terminated: Any, truncated: Any, steps: int, limit: int | None,
               max_wall_s: float | None, start: float) -> str | None:
        rule = self.success_rule
        if not rule.at_end and state["success"] and rule.stop_on_success:
            return "success"
        if terminated:
            return "terminated"
        if truncated:
            return "truncated"
        if limit is not None and steps >= limit:
            return "step_limit"
        if max_wall_s is not None and time.monotonic() - start >= max_wall_s:
            return "time_limit"
        return None

    def _check(self, observation: Any, reward: Any) -> None:
        bad = find_nonfinite(observation)
        if bad is None and reward is not None and not math.isfinite(float(reward)):
            bad = f"reward is {reward}"
        if bad is not None:
            raise _EpisodeEnd("error", f"the environment returned a non-finite value: {bad}")
        self._last_observation = observation

    def _await_action(self, observation: Any, extras: dict[str, Any]) -> Any:
        deadline = time.monotonic() + self.config.action_timeout
        while True:
            wait = min(self.config.resend_interval, deadline - time.monotonic())
            if wait <= 0:
                raise _EpisodeEnd("error", f"no action on {self.action_topic.name!r} within "
                                           f"{self.config.action_timeout:g} s (lockstep)")
            try:
                return self._actions.get(timeout=wait)
            except queue.Empty:
                if self._stop.is_set():
                    raise _EpisodeEnd("interrupted", "the evaluation was stopped") from None
                self._publish_state(observation, extras)  # an agent not matched yet gets it again

    def _to_action(self, value: Any) -> Any:
        try:
            return action_vector(value, self._action_shape, topic=self.action_topic.name, world=self.component_name,
                                 joint_names=self.joint_names)
        except AlgorithmFailure as exc:
            raise _EpisodeEnd("error", str(exc)) from None
