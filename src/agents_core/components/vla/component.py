"""``VLA``: a vision-language-action component that acts on a robot arm through a policy server.

It is an action server (``trigger=None``): a goal of the ``VisionLanguageAction`` type carries a
task sentence. While a goal runs, two loops work on it:

- the *policy loop* (a thread of the goal's) samples an observation at ``observation_sending_rate``
  (joint state as the policy names it, camera images, the task, the control step), sends it
  through the policy client, checks the returned chunk (finite numbers, one entry per action
  name) and queues it in an :class:`~agents_core.components.vla.action_chunks.ActionChunkQueue`, where
  chunks that overlap are aggregated;
- the *control loop* (the goal's thread) pops one action per tick of ``action_sending_rate``, maps
  it onto the robot's joints (``joint_names_map``), clips it to the joint limits (position and,
  from the current position, velocity; from the URDF or the config) and publishes it as a
  JointState, JointTrajectory or JointJog, with feedback ``{step, action, status}``.

The goal ends succeeded after ``max_steps`` (the goal's, else ``config.max_timesteps``) commands or
when the termination event fires (:meth:`VLA.set_termination_trigger`); canceled on a cancel
request; aborted on a bad policy answer (NaN, wrong dimension), joints missing from the state, a
joint state older than ``state_timeout``, an unreachable policy server, or no action for
``action_wait_timeout``. On cancel and abort the robot gets a final *hold* command (its current
positions; zero velocities), the result says why, an abort sets the component's health, and the
next goal starts afresh. A goal arriving while one runs is rejected or preempts it
(``config.on_new_goal``).
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ...declarations.setup_calls import setup_method
from ...errors import AlgorithmFailure, ComponentError, ConfigError, ModelClientError, WiringError
from ...events import Event
from ...messages import JointJogMsg, JointStateMsg, JointTrajectoryMsg, JointTrajectoryPointMsg
from ...runtime.run_type import ComponentRunType
from ...status import HealthStatus, LifecycleState
from ...supported_types import RGBD, Image, JointJog, JointState, JointTrajectory
from ...topics import Topic
from ..model_component import ModelComponent
from ..wiring import AllowedTypes
from .action_chunks import ActionChunkQueue, AggregationFunction, aggregation_function
from .config import VLAConfig
from .urdf import JointLimits, joint_limits_from_config, read_urdf_joint_limits

if TYPE_CHECKING:
    from ...clients.model_base import ModelClient
    from ...transport.contract import Subscription
    from ...transport.goals import GoalHandle

__all__ = ["VLA"]

#: How long a preempting goal waits for the goal it preempts to stop (s).
_PREEMPT_WAIT = 5.0


class _GoalFailure(Exception):
    """Ends a goal as aborted: ``health`` is what the component reports, ``str()`` the reason."""

    def __init__(self, reason: str, health: HealthStatus) -> None:
        super().__init__(reason)
        self.health = health


def _end_goal(outcome: Callable[[], None]) -> None:
    """Set a goal's outcome, unless the server has ended the goal already (it is closing)."""
    with contextlib.suppress(ComponentError):
        outcome()


class _EventFeed:
    """Feeds the values of one topic to an event's condition."""

    def __init__(self, event: Event, topic_name: str) -> None:
        self._event = event
        self._topic_name = topic_name

    def __call__(self, value: Any) -> None:
        self._event.process(self._topic_name, value)


class VLA(ModelComponent):
    """Turns a task sentence, camera images and joint states into joint commands, as an action server.

    :param inputs: one JointState topic and the Image / RGBD topics named in ``config.camera_inputs_map``.
    :param outputs: one JointState, JointTrajectory or JointJog topic (the commands).
    :param model_client: a :class:`~agents_core.clients.policy_base.PolicyClient` such as
        :class:`~agents_core.clients.lerobot.LeRobotClient`.
    :param config: a :class:`~agents_core.config.VLAConfig`.
    :param trigger: must be None (goals drive the component).
    Goals go to :attr:`action_name` (the component name) as ``VisionLanguageAction`` goals.
    """

    config_class = VLAConfig
    handled_outputs = (JointState, JointTrajectory, JointJog)
    _action_type = "VisionLanguageAction"

    def __init__(
        self,
        inputs: Sequence[Topic] | None = None,
        outputs: Sequence[Topic] | None = None,
        model_client: ModelClient | None = None,
        config: VLAConfig | None = None,
        trigger: None = None,
        component_name: str = "vla",
        **kwargs: Any,
    ) -> None:
        if trigger is not None:
            raise WiringError(f"component {component_name!r}: a VLA is driven by goals; its trigger must be None")
        kwargs.setdefault("run_type", ComponentRunType.ACTION_SERVER)
        self.allowed_inputs: AllowedTypes = {"Required": [JointState], "Optional": [Image, RGBD]}
        self.allowed_outputs: AllowedTypes = {"Required": [[JointState, JointTrajectory, JointJog]]}
        super().__init__(inputs=inputs, outputs=outputs, model_client=model_client, config=config, trigger=None,
                         component_name=component_name, **kwargs)
        self.config: VLAConfig
        states = [t for t in self.inputs if issubclass(t.msg_type, JointState)]
        if len(states) != 1:
            raise WiringError(f"component {self.component_name!r}: a VLA takes exactly one JointState input, "
                              f"got {[t.name for t in states]}")
        if len(self.outputs) != 1:
            raise WiringError(f"component {self.component_name!r}: a VLA has exactly one command output, "
                              f"got {[t.name for t in self.outputs]}")
        self._state_topic = states[0]
        self._output_topic = self.outputs[0]
        cameras = {t.name for t in self.inputs if issubclass(t.msg_type, Image)}
        for camera, topic_name in self.config.camera_inputs_map.items():
            if topic_name not in cameras:
                raise WiringError(f"component {self.component_name!r}: camera {camera!r} maps to {topic_name!r}, "
                                  f"which is not one of its Image / RGBD inputs {sorted(cameras)}")
        if not self.config.joint_names_map:
            raise ConfigError(f"component {self.component_name!r}: VLAConfig.joint_names_map is empty; map the "
                              "policy's joint names to the robot's")
        self._aggregate: AggregationFunction = aggregation_function(self.config.aggregation_function)
        self._limits: dict[str, JointLimits] = {}
        self._action_names: list[str] = list(self.config.joint_names_map)
        self._state_received_at = -float("inf")
        self._callbacks_of(self._state_topic.name).on_callback_execute(self._note_state_arrival)
        # The running goal (for preemption) and the lock that makes goals run one at a time.
        self._goal_lock = threading.Lock()
        self._running: GoalHandle | None = None
        self._run_lock = threading.Lock()
        self._policy_thread: threading.Thread | None = None
        self._stop_event: Event | None = None
        self._stop_requested = threading.Event()
        self._event_subscriptions: list[Subscription] = []
        self.goals_finished = 0
        #: How many hold commands were sent (on cancel and abort).
        self.holds_sent = 0

    @classmethod
    def _server_capable(cls) -> bool:
        return True

    def _callbacks_of(self, name: str) -> Any:
        return self.callbacks.get(name) or self.trig_callbacks[name]

    def _note_state_arrival(self, _value: Any) -> None:
        self._state_received_at = time.monotonic()

    # -- settings ----------------------------------------------------------------------------------

    @setup_method
    def set_aggregation_function(self, func: str | AggregationFunction) -> None:
        """How overlapping action chunks combine: a built-in name or ``f(queued, incoming) -> action``."""
        self._aggregate = aggregation_function(func)

    @setup_method
    def set_termination_trigger(self, mode: str = "timesteps", stop_event: Event | None = None,
                                max_timesteps: int | None = None) -> None:
        """How a goal ends successfully: ``"timesteps"`` (after ``max_timesteps`` commands) or ``"event"``
        (when ``stop_event`` fires, e.g. a condition on a topic; the timestep limit still applies)."""
        if mode not in ("timesteps", "event"):
            raise ConfigError(f"component {self.component_name!r}: termination mode must be 'timesteps' or 'event'")
        if mode == "event" and not isinstance(stop_event, Event):
            raise ConfigError(f"component {self.component_name!r}: termination mode 'event' needs a stop_event")
        if max_timesteps is not None:
            self.config.max_timesteps = max_timesteps
        if self._stop_event is not None:
            self._stop_event.remove_listener(self._on_stop_event)
        self._close_event_subscriptions()
        self._stop_event = stop_event if mode == "event" else None
        self._watch_stop_event(subscribe=self.lifecycle_state == LifecycleState.ACTIVE)

    def _watch_stop_event(self, subscribe: bool) -> None:
        """Listen to the termination event; ``subscribe``: feed it from its topics now (the component is, or is
        becoming, active; set before the launch, the event is subscribed to when the component activates)."""
        event = self._stop_event
        if event is None:
            return
        event.add_listener(self._on_stop_event)
        if subscribe:
            for topic in event.topics.values():
                self._event_subscriptions.append(self.transport.create_subscription(
                    topic, _EventFeed(event, topic.name), owner=self.component_name))

    def _close_event_subscriptions(self) -> None:
        for sub in self._event_subscriptions:
            sub.close()
        self._event_subscriptions.clear()

    def _on_stop_event(self, _event: Event, _values: Mapping[str, Any]) -> None:
        self._stop_requested.set()

    # -- lifecycle ---------------------------------------------------------------------------------

    def custom_on_configure(self) -> None:
        limits: dict[str, JointLimits] = {}
        if self.config.robot_urdf_file is not None:
            limits.update(read_urdf_joint_limits(self.config.robot_urdf_file))
            unknown = sorted(set(self.config.joint_names_map.values()) - set(limits))
            if unknown:
                raise ConfigError(f"component {self.component_name!r}: joint(s) {unknown} of joint_names_map are "
                                  f"not commanded joints of {self.config.robot_urdf_file}")
        if self.config.joint_limits:
            limits.update(joint_limits_from_config(self.config.joint_limits, "VLAConfig"))
        self._limits = limits
        super().custom_on_configure()
        declared = getattr(self.model_client, "action_names", None)
        if declared:
            unknown = [name for name in declared if name not in self.config.joint_names_map]
            if unknown:
                raise ConfigError(f"component {self.component_name!r}: the policy commands joint(s) {unknown} that "
                                  "joint_names_map does not map to the robot; they would never be sent")
            self._action_names = list(declared)

    def custom_on_activate(self) -> None:
        super().custom_on_activate()
        self._close_event_subscriptions()
        self._watch_stop_event(subscribe=True)  # the state says "inactive" until this hook returns

    def custom_on_deactivate(self) -> None:
        with self._goal_lock:
            running = self._running
        if running is not None:
            running.request_cancel()
            # Let the goal send its hold command while the output is still open (bounded).
            if self._run_lock.acquire(timeout=_PREEMPT_WAIT):
                self._run_lock.release()
        self._close_event_subscriptions()
        super().custom_on_deactivate()

    # -- goals -------------------------------------------------------------------------------------

    def _accept_goal(self, goal: dict[str, Any]) -> bool:
        if self.lifecycle_state != LifecycleState.ACTIVE:
            return False
        with self._goal_lock:
            running = self._running
            if running is None:
                return True
            if self.config.on_new_goal == "reject":
                self._logger.info("goal %r rejected: a goal is running (on_new_goal='reject')", goal.get("task"))
                return False
        self._logger.info("goal %r preempts the running goal", goal.get("task"))
        running.request_cancel()
        return True

    def main_action_callback(self, goal_handle: GoalHandle) -> dict[str, Any]:
        """Run one goal to its end (on the goal's own thread); returns ``{success, message, steps}``."""
        if not self._run_lock.acquire(timeout=_PREEMPT_WAIT):
            goal_handle.abort("the previous goal did not stop in time")
            return {"success": False, "message": "the previous goal did not stop in time", "steps": 0}
        try:
            with self._goal_lock:
                self._running = goal_handle
            return self._run_goal(goal_handle)
        finally:
            with self._goal_lock:
                if self._running is goal_handle:
                    self._running = None
            self.goals_finished += 1
            self._run_lock.release()

    def _run_goal(self, handle: GoalHandle) -> dict[str, Any]:
        try:
            # The policy server may have been down at configure: the component came up unhealthy
            # and each goal tries the setup again.
            self._ensure_client_ready()
        except ModelClientError as exc:
            return self._abort(handle, f"the policy server failed: {exc}", HealthStatus.COMPONENT_FAILURE, 0)
        task = str(handle.goal.get("task", ""))
        max_steps = int(handle.goal.get("max_steps") or 0) or self.config.max_timesteps
        queue = ActionChunkQueue(self._aggregate)
        stop = threading.Event()
        failure: list[_GoalFailure] = []
        self._stop_requested.clear()
        policy = threading.Thread(target=self._policy_loop, args=(task, queue, stop, failure),
                                  name=f"{self.component_name}:policy", daemon=True)
        previous = self._policy_thread
        if previous is not None and previous.is_alive():
            # The last goal's policy call is still in flight: one client serves one call at a time.
            previous.join(timeout=float(getattr(self.model_client, "inference_timeout", 5.0)))
        self._policy_thread = policy
        steps = 0
        period = 1.0 / self.config.action_sending_rate
        last_action = time.monotonic()
        next_tick = time.monotonic()
        policy.start()
        try:
            while True:
                if handle.cancel_requested:
                    self._send_hold()
                    _end_goal(handle.canceled)
                    return {"success": False, "message": "canceled", "steps": steps}
                if failure:
                    raise failure[0]
                if self._stop_requested.is_set():
                    return self._succeed(handle, "the termination event fired", steps)
                item = queue.pop_next()
                now = time.monotonic()
                if item is not None:
                    command = self._command(item[1])
                    self._publish_command(command)
                    steps += 1
                    last_action = now
                    handle.publish_feedback({"step": steps, "action": command["values"], "status": "executing"})
                    if steps >= max_steps:
                        return self._succeed(handle, f"{steps} steps done", steps)
                elif now - last_action > self.config.action_wait_timeout:
                    raise _GoalFailure(f"no action from the policy for {self.config.action_wait_timeout} s",
                                       HealthStatus.COMPONENT_FAILURE)
                next_tick = max(next_tick + period, time.monotonic())
                handle.wait_for_cancel(next_tick - time.monotonic())
        except _GoalFailure as exc:
            return self._abort(handle, str(exc), exc.health, steps)
        except Exception as exc:  # a publish on a closing transport, a bug: the robot still gets its hold
            self._logger.exception("goal failed")
            return self._abort(handle, f"{type(exc).__name__}: {exc}", HealthStatus.COMPONENT_FAILURE, steps)
        finally:
            stop.set()
            # Not the whole inference timeout: a policy call still in flight ends on its own (its chunk
            # goes to this goal's queue, which nobody reads), and the result must not wait for it.
            policy.join(timeout=1.0)

    def _succeed(self, handle: GoalHandle, message: str, steps: int) -> dict[str, Any]:
        _end_goal(handle.succeed)
        if self.health_status != HealthStatus.HEALTHY:
            self._set_health(HealthStatus.HEALTHY, "")
        return {"success": True, "message": message, "steps": steps}

    def _abort(self, handle: GoalHandle, reason: str, health: HealthStatus, steps: int) -> dict[str, Any]:
        self._logger.warning("goal aborted: %s", reason)
        try:
            self._send_hold()
        except Exception as exc:  # the abort (and its reason) must reach the client anyway
            self._logger.error("hold command not sent: %s", exc)
        self._set_health(health, reason)
        _end_goal(lambda: handle.abort(reason))
        return {"success": False, "message": reason, "steps": steps}

    # -- the policy loop ---------------------------------------------------------------------------

    def _policy_loop(self, task: str, queue: ActionChunkQueue, stop: threading.Event,
                     failure: list[_GoalFailure]) -> None:
        period = 1.0 / self.config.observation_sending_rate
        while not stop.is_set():
            started = time.monotonic()
            try:
                observation = self._create_input(task, queue.last_played + 1)
                result = self._call_inference(observation)
                first, chunk = int(result.get("timestep", observation["timestep"])), result["output"]
                if first > observation["timestep"]:
                    # A chunk starts at the step of the observation it answers (or earlier, for an older
                    # one); a later start would jump the control loop ahead of every other chunk.
                    raise AlgorithmFailure(f"the policy answered the observation of step {observation['timestep']} "
                                           f"with actions from step {first}")
                queue.add_chunk(first, self._checked_chunk(chunk))
            except _GoalFailure as exc:
                failure.append(exc)
                return
            except AlgorithmFailure as exc:
                failure.append(_GoalFailure(str(exc), HealthStatus.ALGORITHM_FAILURE))
                return
            except ModelClientError as exc:
                if not stop.is_set():
                    failure.append(_GoalFailure(f"the policy server failed: {exc}", HealthStatus.COMPONENT_FAILURE))
                return
            except Exception as exc:  # a bug must end the goal, not leave it waiting for actions
                failure.append(_GoalFailure(f"{type(exc).__name__}: {exc}", HealthStatus.COMPONENT_FAILURE))
                return
            stop.wait(max(0.0, period - (time.monotonic() - started)))

    def _checked_chunk(self, chunk: Any) -> np.ndarray:
        try:
            rows = np.asarray(chunk, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise AlgorithmFailure(f"the policy's action chunk is not numeric: {exc}") from exc
        if rows.ndim == 1:
            rows = rows[None, :]
        if rows.ndim != 2 or rows.shape[0] == 0:
            raise AlgorithmFailure(f"the policy's action chunk has shape {rows.shape}; expected (n_actions, dim)")
        if rows.shape[1] != len(self._action_names):
            raise AlgorithmFailure(f"the policy sent actions of dimension {rows.shape[1]}; expected "
                                   f"{len(self._action_names)} ({self._action_names})")
        if not np.isfinite(rows).all():
            raise AlgorithmFailure("the policy sent non-finite actions (NaN or infinity); nothing of that chunk "
                                   "was sent")
        return rows

    def _fresh_state(self) -> JointStateMsg:
        msg = self._callbacks_of(self._state_topic.name).msg
        if msg is None:
            raise _GoalFailure(f"no joint state on {self._state_topic.name!r} yet", HealthStatus.SYSTEM_FAILURE)
        age = time.monotonic() - self._state_received_at
        if age > self.config.state_timeout:
            raise _GoalFailure(f"the joint state on {self._state_topic.name!r} is stale ({age:.2f} s old, "
                               f"state_timeout {self.config.state_timeout} s)", HealthStatus.SYSTEM_FAILURE)
        assert isinstance(msg, JointStateMsg)
        return msg

    def _joint_values(self, msg: JointStateMsg, field: str, joints: Sequence[str]) -> np.ndarray:
        values = getattr(msg, field)
        missing = [j for j in joints if j not in msg.name]
        if missing:
            raise _GoalFailure(f"joint(s) {missing} missing from the state on {self._state_topic.name!r} "
                               f"(it has {msg.name})", HealthStatus.SYSTEM_FAILURE)
        if len(values) != len(msg.name):
            raise _GoalFailure(f"the state on {self._state_topic.name!r} has no {field}", HealthStatus.SYSTEM_FAILURE)
        index = {name: i for i, name in enumerate(msg.name)}
        return np.array([float(values[index[j]]) for j in joints])

    def _create_input(self, task: str, step: int, *args: Any, **kwargs: Any) -> dict[str, Any]:
        """The policy's observation for ``step`` of ``task``: the joint state, the cameras, the task text."""
        return self._observation(task, step)

    def _observation(self, task: str, step: int) -> dict[str, Any]:
        msg = self._fresh_state()
        field = {"positions": "position", "velocities": "velocity", "efforts": "effort"}[self.config.state_input_type]
        policy_names = list(self.config.joint_names_map)
        values = self._joint_values(msg, field, [self.config.joint_names_map[n] for n in policy_names])
        images = {}
        for camera, topic_name in self.config.camera_inputs_map.items():
            image = self._callbacks_of(topic_name).get_output()
            if image is None:
                raise _GoalFailure(f"no image on {topic_name!r} (camera {camera!r}) yet", HealthStatus.SYSTEM_FAILURE)
            images[camera] = image
        return {"state": dict(zip(policy_names, values.tolist(), strict=True)), "images": images, "task": task,
                "timestep": step}

    # -- commands ----------------------------------------------------------------------------------

    def _command(self, action: np.ndarray) -> dict[str, Any]:
        """The robot joints and the clipped values of one action (positions or velocities)."""
        joints = []
        for name in self._action_names:
            joint = self.config.joint_names_map.get(name)
            if joint is None:  # checked at configure; kept as a guard: never send an unmapped joint
                raise _GoalFailure(f"the policy commands unknown joint {name!r}", HealthStatus.ALGORITHM_FAILURE)
            joints.append(joint)
        current = self._joint_values(self._fresh_state(), "position", joints)
        dt = 1.0 / self.config.action_sending_rate
        values = []
        for joint, value, now in zip(joints, action.tolist(), current.tolist(), strict=True):
            limits = self._limits.get(joint, JointLimits())
            if self.config.action_output_type == "positions":
                values.append(limits.clip_position(value, now, dt))
            else:
                velocity = limits.clip_velocity(value)
                # At a position limit, only motion back inside it is allowed.
                if (limits.upper is not None and now >= limits.upper and velocity > 0) or (
                        limits.lower is not None and now <= limits.lower and velocity < 0):
                    velocity = 0.0
                values.append(velocity)
        return {"joints": joints, "values": values, "current": current.tolist(),
                "kind": self.config.action_output_type}

    def _publish_command(self, command: dict[str, Any]) -> None:
        joints, values, current = command["joints"], command["values"], command["current"]
        dt = 1.0 / self.config.action_sending_rate
        msg_type = self._output_topic.msg_type
        positions = command["kind"] == "positions"
        value: Any
        if issubclass(msg_type, JointState):
            value = JointStateMsg(name=joints, position=values if positions else [],
                                  velocity=[] if positions else values)
        elif issubclass(msg_type, JointTrajectory):
            point = (JointTrajectoryPointMsg(positions=values, time_from_start=dt) if positions
                     else JointTrajectoryPointMsg(velocities=values, time_from_start=dt))
            value = JointTrajectoryMsg(joint_names=joints, points=[point])
        else:
            value = (JointJogMsg(joint_names=joints, displacements=np.subtract(values, current), duration=dt)
                     if positions else JointJogMsg(joint_names=joints, velocities=values, duration=dt))
        self.publishers_dict[self._output_topic.name].publish(value)

    def _send_hold(self) -> None:
        """Command the mapped joints to stay where they are: their current positions (those the latest state
        has; a joint missing from it cannot be held in place), or zero velocities."""
        joints = [self.config.joint_names_map[n] for n in self._action_names]
        msg = self._callbacks_of(self._state_topic.name).msg
        known: dict[str, float] = {}
        if isinstance(msg, JointStateMsg) and len(msg.position) == len(msg.name):
            known = {name: float(p) for name, p in zip(msg.name, msg.position.tolist(), strict=True)}
        if self.config.action_output_type == "positions":
            held = [j for j in joints if j in known]
            if not held:
                self._logger.error("no hold command: the current positions of %s are unknown", joints)
                return
            if len(held) < len(joints):
                self._logger.warning("hold command without %s: their positions are unknown",
                                     sorted(set(joints) - set(held)))
            current = [known[j] for j in held]
            self._publish_command({"joints": held, "values": current, "current": current, "kind": "positions"})
        else:
            current = [known.get(j, 0.0) for j in joints]
            self._publish_command({"joints": joints, "values": [0.0] * len(joints), "current": current,
                                   "kind": "velocities"})
        self.holds_sent += 1

    # -- ModelComponent hooks ----------------------------------------------------------------------

    def _execution_step(self, **kwargs: Any) -> None:
        """Unused: a VLA acts in goals (:meth:`main_action_callback`), not in steps."""

    def _warmup(self, *args: Any, **kwargs: Any) -> None:
        """No warm-up: the first goal's first observation loads the policy's caches."""
