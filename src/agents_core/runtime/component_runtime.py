"""``ComponentRuntime``: what runs one component, as an object of its own.

A :class:`~agents_core.components.component_base.Component` is a declaration (inputs, outputs,
trigger, config, ``_execution_step``, the ``custom_on_*`` hooks). Its runtime owns everything that
exists only while it runs: the transport it is bound to, its serial worker, the lifecycle machine,
health and fallbacks, presence and services, subscriptions, timers and the goal server. It calls
the component only through its hooks. A launcher (or a test) talks to ``component.runtime``:

- :meth:`ComponentRuntime.bind`: attach to a transport (presence with the status topic, the
  ``execute_method`` / ``set_param`` / ``describe`` services, the serial worker);
- :meth:`ComponentRuntime.submit_action`: run an event's action on the worker, between steps;
- :meth:`ComponentRuntime.hurry`: stop waiting for a running step (a second Ctrl-C).

An ACTION_SERVER component whose class sets ``_action_type`` serves goals on
``component.action_name`` while active (execute: ``main_action_callback``, accept:
``_accept_goal``); each goal runs on a thread of its own, never on the step worker.
"""

from __future__ import annotations

import functools
import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import Future
from typing import TYPE_CHECKING, Any

from ..config import configure_time_fields
from ..declarations.setup_calls import freeze_record
from ..errors import (
    AlgorithmFailure,
    ClientConnectionError,
    ComponentError,
    ConfigError,
    InferenceConnectionError,
    ModelClientError,
    RequestTimeoutError,
    TransportError,
    WiringError,
)
from ..events import Event
from ..status import HealthStatus, LifecycleState
from ..telemetry import switch as _telemetry
from ..topics import FixedInput
from ..transport.requests import check_timeout, request_deadline
from .figures import StepFigures
from .health import Health
from .lifecycle import LifecycleMachine
from .run_type import ComponentRunType
from .services import SERVICE_NAMES, ComponentServices
from .worker import PeriodicTimer, StepWorker, WorkerStatistics

if TYPE_CHECKING:
    from ..transport.contract import ActionServer, ComponentPresence, ServiceServer, Subscription, Transport
    from ..transport.delivery import SubscriptionStatistics
    from .hooks import ComponentHooks

__all__ = ["ComponentRuntime", "describe_trigger", "is_algorithm_failure"]

# Read for every input value and every step: an enum member looked up once (a class attribute
# lookup on an Enum costs ~0.1 µs on Python 3.11).
_ACTIVE = LifecycleState.ACTIVE


def is_algorithm_failure(exc: BaseException) -> bool:
    """Whether a step's exception is an ALGORITHM_FAILURE rather than a COMPONENT_FAILURE.

    As upstream: any inference that fails at run time (the server answered an error, timed out,
    sent something unreadable or nothing, or went away: :class:`~agents_core.errors.InferenceConnectionError`)
    is an algorithm failure, and so is :class:`~agents_core.errors.AlgorithmFailure`. A client
    whose *setup* cannot reach its server (a plain :class:`~agents_core.errors.ClientConnectionError`
    from ``check_connection``, a database client that cannot connect) is a component failure, like
    a model setup that fails at configure.
    """
    if isinstance(exc, AlgorithmFailure | InferenceConnectionError):
        return True
    return isinstance(exc, ModelClientError) and not isinstance(exc, ClientConnectionError)


def describe_trigger(trigger: Any, run_type: ComponentRunType) -> str:
    """One line saying when a component runs its steps (logged at activate)."""
    if run_type == ComponentRunType.TIMED:
        rate = float(trigger)
        return f"trigger: a timer at {rate:g} Hz (a step every {1.0 / rate:.3g} s)"
    if isinstance(trigger, Event):
        return f"trigger: event {trigger.name!r}"
    names = [t.name for t in (trigger if isinstance(trigger, list | tuple) else [trigger]) if hasattr(t, "name")]
    if names:
        return f"trigger: a message on {', '.join(repr(n) for n in names)}"
    return f"trigger: none ({run_type.value}: answers requests)"


class ComponentRuntime:
    """What runs ``component`` (see the module docstring)."""

    def __init__(self, component: ComponentHooks) -> None:
        self._component = component
        self._name = component.component_name
        self._logger = component.get_logger()
        self.lifecycle = LifecycleMachine(self._name, on_failed=self._on_transition_failed,
                                          on_done=self._on_transition_done)
        self.health = Health(self._logger, self.report_status)
        self._services = ComponentServices(component, self.run_on_worker, self.set_params)
        self._transport: Transport | None = None
        self._worker: StepWorker | None = None
        self._presence: ComponentPresence | None = None
        self._served: list[ServiceServer] = []
        self._action_server: ActionServer | None = None
        self._subscriptions: list[Subscription] = []
        self._timers: list[PeriodicTimer] = []
        self._status_timer: PeriodicTimer | None = None
        # Bumped by every deactivate: a step that started under an older epoch was overtaken by
        # it, and its outputs and failures are discarded (counted), never reported as failures.
        self._epoch = 0
        self._step_epoch: int | None = None
        self._accepting_steps = False
        self._discarded_outputs = 0
        self._overtaken_steps = 0
        # Set by hurry() (a second Ctrl-C): stop waiting for a running step.
        self._hurry = threading.Event()
        #: Step durations and counters behind the status's ``stats`` (``agentsctl top``).
        self.figures = StepFigures()

    # -- what it is now -----------------------------------------------------------------------

    @property
    def name(self) -> str:
        """The component's name."""
        return self._name

    @property
    def is_bound(self) -> bool:
        """Whether the component is attached to a transport."""
        return self._transport is not None

    @property
    def transport(self) -> Transport:
        """The transport the component was launched on (ComponentError before)."""
        if self._transport is None:
            raise ComponentError(f"component {self._name!r} is not launched (add it to a Launcher)")
        return self._transport

    @property
    def state(self) -> LifecycleState:
        """The current lifecycle state."""
        return self.lifecycle.state

    @property
    def worker(self) -> StepWorker | None:
        """The serial worker (None until bound)."""
        return self._worker

    @property
    def status_timer(self) -> PeriodicTimer | None:
        """The timer that republishes the status while active (None otherwise)."""
        return self._status_timer

    @property
    def discarded_outputs(self) -> int:
        """Outputs of steps overtaken by a deactivate, discarded instead of published."""
        return self._discarded_outputs

    @property
    def overtaken_steps(self) -> int:
        """Steps that were running when a deactivate came, whose results were discarded."""
        return self._overtaken_steps

    def worker_statistics(self) -> WorkerStatistics:
        """Counters of the serial worker (all zero before it is bound)."""
        return WorkerStatistics() if self._worker is None else self._worker.statistics()

    def input_statistics(self) -> dict[str, SubscriptionStatistics]:
        """Counters of each input subscription while active."""
        return {sub.topic.name: sub.statistics() for sub in list(self._subscriptions)}

    # -- binding ------------------------------------------------------------------------------

    def bind(self, transport: Transport) -> None:
        """Attach to ``transport``: declare the presence (and status topic), the services, start the worker."""
        c = self._component
        if self._transport is not None:
            raise ComponentError(f"component {self._name!r} is already launched")
        if c.run_type == ComponentRunType.ACTION_SERVER and not transport.capabilities.actions:
            raise WiringError(f"component {self._name!r} runs as an action server, but the "
                              f"{transport.name!r} transport has no long-running goals (actions)")
        freeze_record(c)  # what the recipe assigned until now; the running component's own changes are not
        self._transport = transport
        self._worker = StepWorker(self._name, c.config.execution_queue_depth, c.config.queue_full_policy)
        self._presence = transport.declare_component(self._name, on_transition=self._external_transition,
                                                     pending=lambda: self.worker_statistics().pending)
        for service in SERVICE_NAMES:
            # inline: each handler returns by its caller's deadline and runs the component's code only
            # on its worker (run_on_worker), so a local caller may run the handler itself.
            self._served.append(transport.create_service(f"{self._name}/{service}", self._services.handler(service),
                                                         owner=self._name, inline=True))
        _telemetry.runtimes.add(self)
        self.report_status()

    def submit_action(self, func: Callable[[], Any]) -> Future[Any]:
        """Run ``func`` on the component's worker, ahead of pending steps; ComponentError if not bound."""
        if self._worker is None:
            raise ComponentError(f"component {self._name!r} is not launched")
        return self._worker.submit_control(func)

    def hurry(self) -> None:
        """Stop waiting for a running step in deactivate and shutdown."""
        self._hurry.set()

    def report_status(self) -> None:
        """Publish the current lifecycle state and health on the presence (and status topic)."""
        presence = self._presence
        if presence is None:
            return
        try:
            presence.update(self.lifecycle.state, self.health.status, self.health.message,
                            stats=self.figures.text(self))
        except TransportError as exc:
            self._logger.debug("status not published: %s", exc)

    # -- lifecycle ----------------------------------------------------------------------------

    def transition(self, name: str) -> None:
        """Run lifecycle transition ``name`` ("configure", "activate", ...); LifecycleError if not allowed."""
        body = {"configure": self._do_configure, "activate": self._do_activate, "deactivate": self._do_deactivate,
                "cleanup": self._do_cleanup, "shutdown": self._do_shutdown}[name]
        self.lifecycle.run(name, body)

    def shutdown(self) -> None:
        """Any state -> finalized, deactivating first if active; nothing when already finalized."""
        with self.lifecycle.lock:
            if self.state == LifecycleState.FINALIZED:
                return
            if self.state == LifecycleState.ACTIVE:
                self._component.deactivate()
            self.transition("shutdown")

    def restart(self) -> None:
        """Back to active from any state but finalized (see ``Component.restart``)."""
        c = self._component
        with self.lifecycle.lock:
            state = self.state
            if state == LifecycleState.ACTIVE:
                c.deactivate()
            elif state == LifecycleState.ERROR:
                c.cleanup()
            if self.state == LifecycleState.UNCONFIGURED:
                c.configure()
            c.activate()

    def stop(self) -> None:
        """Deactivate when active; nothing in any other state (see ``Component.stop``)."""
        with self.lifecycle.lock:
            if self.state == LifecycleState.ACTIVE:
                self._component.deactivate()

    def model_latency_ms(self) -> float | None:
        """The last model call's latency in ms (a model component's client), None without one."""
        seconds = getattr(getattr(self._component, "model_client", None), "last_inference_seconds", None)
        return round(seconds * 1e3, 2) if isinstance(seconds, int | float) else None

    def _on_transition_failed(self, name: str, exc: Exception) -> None:
        self.health.set(HealthStatus.COMPONENT_FAILURE, f"{name} failed: {exc}")

    def _on_transition_done(self, name: str, target: LifecycleState) -> None:
        self._logger.info("%s -> %s", name, target.value)
        self.report_status()

    def _external_transition(self, transition: str) -> bool:
        """Run a transition asked from outside (lifecycle service, queryable); never raises."""
        c = self._component
        method = {"configure": c.configure, "activate": c.activate, "deactivate": c.deactivate,
                  "cleanup": c.cleanup, "shutdown": c.shutdown}.get(transition)
        if method is None:
            self._logger.warning("unknown lifecycle transition %r requested", transition)
            return False
        try:
            method()
        except Exception as exc:
            self._logger.warning("transition %r requested from outside failed: %s", transition, exc)
            return False
        return True

    def _do_configure(self) -> None:
        self._component.custom_on_configure()

    def _do_activate(self) -> None:
        c = self._component
        transport = self.transport
        self._accepting_steps = True
        self.figures.activations += 1
        topics = {t.name: t for t in (*c.inputs, *c.outputs)}
        for name, pub in c.publishers_dict.items():
            pub.attach(transport.create_publisher(topics[name], owner=self._name))
        for t in c.inputs:
            if isinstance(t, FixedInput):
                continue
            cb = c.callbacks.get(t.name) or c.trig_callbacks[t.name]
            # Inline: the middleware's thread stores the value and enqueues the step on this
            # component's worker, whose bounded queue is then the only queue of the hop.
            self._subscriptions.append(transport.create_subscription(t, cb._receive, owner=self._name, inline=True))
        c.activate_all_triggers()
        self._status_timer = PeriodicTimer(c.config.status_rate, self.report_status, f"{self._name}:status")
        c.custom_on_activate()
        self._open_action_server()

    def start_triggers(self) -> None:
        """Start the timer of a float trigger, or listen to a trigger Event (``Component.activate_all_triggers``)."""
        c = self._component
        self._logger.info("%s", describe_trigger(c.trigger, c.run_type))
        if c.run_type == ComponentRunType.TIMED:
            assert isinstance(c.trigger, int | float)
            if not self._timers:
                self._timers.append(PeriodicTimer(float(c.trigger), self._submit_timed_step,
                                                  f"{self._name}:trigger"))
        elif isinstance(c.trigger, Event):
            c.trigger.remove_listener(self._on_trigger_event)
            c.trigger.add_listener(self._on_trigger_event)

    def _do_deactivate(self) -> None:
        c = self._component
        # First of all: no new step starts, and the running one (if any) is overtaken.
        self._accepting_steps = False
        self._epoch += 1
        self._close_action_server()
        c.custom_on_deactivate()
        if isinstance(c.trigger, Event):
            c.trigger.remove_listener(self._on_trigger_event)
        for timer in self._timers:
            timer.stop()
        self._timers.clear()
        if self._status_timer is not None:
            self._status_timer.stop()
            self._status_timer = None
        for sub in self._subscriptions:
            sub.close()
        self._subscriptions.clear()
        worker = self._worker
        if worker is not None:
            dropped = worker.discard_steps()
            if dropped:
                self._logger.info("discarded %d pending step(s) on deactivate", dropped)
            if not worker.on_worker_thread and not worker.wait_step_done(c.config.step_finish_timeout, self._hurry):
                self._logger.info("a step is still running after %.1f s; its outputs will be discarded",
                                  c.config.step_finish_timeout)
        for pub in c.publishers_dict.values():
            pub.detach()
        self.health.stopped()  # a failure counted since its line: how many times, before the component stops

    def _do_cleanup(self) -> None:
        self._component.custom_on_cleanup()

    def _do_shutdown(self) -> None:
        c = self._component
        c.custom_on_shutdown()
        if self._worker is not None:
            self._worker.stop(timeout=max(c.config.step_finish_timeout, 1.0), abort=self._hurry)
        for srv in self._served:
            srv.close()
        self._served.clear()
        if self._presence is not None:
            self._presence.close()
            self._presence = None

    # -- goals --------------------------------------------------------------------------------

    def _open_action_server(self) -> None:
        """Serve the component's goals (at activate), if it is an action server with an ``_action_type``."""
        c = self._component
        action_type = c._action_type
        if c.run_type != ComponentRunType.ACTION_SERVER or action_type is None or self._action_server is not None:
            return
        self._action_server = self.transport.create_action_server(c.action_name, action_type, c.main_action_callback,
                                                                  owner=self._name, accept=c._accept_goal)

    def _close_action_server(self) -> None:
        """Stop serving goals (at deactivate): goals still running end ABORTED with the reason."""
        server, self._action_server = self._action_server, None
        if server is not None:
            server.close()

    # -- triggers and steps -------------------------------------------------------------------

    def _submit_timed_step(self) -> None:
        self.submit_step({})

    def _on_trigger_event(self, event: Event, values: Mapping[str, Any]) -> None:
        self.submit_step({"event": event})

    def submit_step(self, kwargs: dict[str, Any], snapshot: tuple[str, Any] | None = None) -> None:
        """Queue one ``_execution_step(**kwargs)``; ``snapshot`` is (trigger topic, the value that fired)."""
        worker = self._worker
        if worker is None:
            return
        if self.lifecycle.state != _ACTIVE or not self._accepting_steps:
            # Arrived while (de)activating: discarded, and counted as such.
            worker.count_discarded()
            return
        # A partial, not a lambda: this runs on the transport's thread for every input value, and
        # the worker then calls _run_step without an extra Python frame.
        tel = _telemetry.hooks
        if tel is None:
            worker.submit_step(functools.partial(self._run_step, kwargs, snapshot, self._epoch))
        else:  # the trace context of the value that triggered the step goes with it to the worker
            worker.submit_step(functools.partial(self._run_traced_step, tel, tel.capture(), kwargs, snapshot,
                                                 self._epoch))

    def in_overtaken_step(self) -> bool:
        """True on the worker thread, in a step that a deactivate has overtaken."""
        return (self._worker is not None and self._worker.on_worker_thread and self._step_epoch is not None
                and self._step_epoch != self._epoch)

    def discard_output(self, topic_name: str) -> None:
        """Count an output of an overtaken step that was not published."""
        self._discarded_outputs += 1
        self._logger.debug("discarded an output on %r: the component was deactivated during the step", topic_name)

    def _run_traced_step(self, tel: _telemetry.Hooks, context: object, kwargs: dict[str, Any],
                         snapshot: tuple[str, Any] | None, epoch: int) -> None:
        if self.lifecycle.state != _ACTIVE or epoch != self._epoch:
            return
        token = tel.step(self._name, context)
        try:
            self._run_step(kwargs, snapshot, epoch)
        finally:
            tel.step_end(token)

    def _run_step(self, kwargs: dict[str, Any], snapshot: tuple[str, Any] | None, epoch: int) -> None:
        if self.lifecycle.state != _ACTIVE or epoch != self._epoch:
            return
        c = self._component
        cb = None
        if snapshot is not None:
            cb = c.trig_callbacks[snapshot[0]]
            cb._begin_step(snapshot[1])
        self._step_epoch = epoch
        started = time.perf_counter()
        try:
            c._execution_step(**kwargs)
        except Exception as exc:
            if epoch != self._epoch:
                # Deactivated under the step: whatever failed (a closed publisher, a cancelled
                # stream) failed because the component was asked to stop.
                self._overtaken_steps += 1
                self._logger.debug("a step overtaken by deactivate ended with %s: %s", type(exc).__name__, exc)
            elif is_algorithm_failure(exc):
                self.health.step_failed(HealthStatus.ALGORITHM_FAILURE, exc)
            elif isinstance(exc, TransportError):
                self.health.step_failed(HealthStatus.SYSTEM_FAILURE, exc)
            else:
                self.health.step_failed(HealthStatus.COMPONENT_FAILURE, exc)
        else:
            if epoch != self._epoch:
                self._overtaken_steps += 1
                return
            self.health.step_succeeded()
        finally:
            self.figures.add(time.perf_counter() - started)
            self._step_epoch = None
            if cb is not None:
                cb._end_step()

    # -- work asked from outside the steps ----------------------------------------------------

    def run_on_worker(self, func: Callable[[], Any], timeout: float = 30.0) -> Any:
        """Run ``func`` on the worker (between steps) and return its result (see ``Component.run_on_worker``)."""
        if self._worker is None or self._worker.on_worker_thread:
            return func()
        timeout = check_timeout(timeout, f"component {self._name!r}: run_on_worker")
        deadline = time.monotonic() + timeout
        caller_deadline = request_deadline()
        if caller_deadline is not None:
            deadline = min(deadline, caller_deadline)
        future = self._worker.submit_control(func, deadline=deadline)
        try:
            return future.result(timeout=max(0.0, deadline - time.monotonic()))
        except TimeoutError:
            if future.cancel():
                raise RequestTimeoutError(f"component {self._name!r}: the worker did not get to the "
                                          f"request within {timeout:g} s (busy with a step?)") from None
            if not future.done():
                raise RequestTimeoutError(f"component {self._name!r}: the request did not finish within "
                                          f"{timeout:g} s") from None
            raise

    def set_params(self, params: dict[str, Any]) -> None:
        """Change config fields, validated, applied at once (see ``Component.set_params``)."""
        config = self._component.config
        at_configure = sorted(set(params) & configure_time_fields(config))
        if at_configure and self.state != LifecycleState.UNCONFIGURED:
            raise ConfigError(f"component {self._name!r}: {at_configure} apply at configure only; "
                              "deactivate and clean up the component, set them, then configure it again")
        self.run_on_worker(lambda: self._apply_params(params), timeout=10.0)

    def _apply_params(self, params: dict[str, Any]) -> None:
        config = self._component.config
        config.update(**params)
        changed = set(params)
        if "log_level" in changed:
            self._logger.setLevel(config.log_level.upper())
        if self._worker is not None and changed & {"execution_queue_depth", "queue_full_policy"}:
            self._worker.set_queue(config.execution_queue_depth, config.queue_full_policy)
        if "status_rate" in changed and self._status_timer is not None:
            self._status_timer.stop()
            self._status_timer = PeriodicTimer(config.status_rate, self.report_status, f"{self._name}:status")
