"""``Component``: inputs and outputs, triggers, lifecycle, health, fallbacks, actions.

Subclass it for processing that needs no model (subclass
:class:`~agents_core.components.model_component.ModelComponent` otherwise) and implement
``_execution_step(**kwargs)``. Declare ``self.allowed_inputs`` / ``self.allowed_outputs``
before calling ``super().__init__``::

    self.allowed_inputs = {"Required": [Image, [String, Audio]], "Optional": [CompressedImage]}

Each ``Required`` entry needs at least one topic of that type (a list entry: of any of its
types); every topic given must match some entry; subclasses of a listed type match it.

The component's steps, actions and fallbacks all run on its own serial worker (see
:mod:`agents_core.components.worker`).
"""

from __future__ import annotations

import copy
import logging
import threading
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..actions import Action, Fallback
from ..callbacks import GenericCallback, callback_for
from ..config import BaseComponentConfig
from ..errors import AlgorithmFailure, ComponentError, ConfigError, TransportClosedError, TransportError, WiringError
from ..events import Event
from ..status import HealthStatus, LifecycleState
from ..topics import FixedInput, Topic, validate_topic_name
from ..transport.core import status_topic
from ..transport.delivery import SubscriptionStatistics
from .health import HealthAndFallbacks
from .lifecycle import LifecycleMachine
from .run_type import ComponentRunType
from .runtime import ComponentRuntime
from .services import ComponentServices
from .wiring import AllowedTypes, TriggerType, check_topic_list, resolve_run_type, trigger_topics, validate_topics
from .worker import PeriodicTimer, StepWorker, WorkerStatistics

if TYPE_CHECKING:
    from ..transport.contract import (
        ActionServer,
        ComponentPresence,
        Publisher,
        ServiceServer,
        Subscription,
        Transport,
    )
    from ..transport.goals import GoalHandle

__all__ = ["AllowedTypes", "Component", "ComponentPublisher", "TriggerType"]


class ComponentPublisher:
    """A component's publisher for one output topic, applying its pre-processors before sending."""

    def __init__(self, topic: Topic, component: Component) -> None:
        self.topic = topic
        self._component = component
        self._preprocessors: list[Callable[[Any], Any]] = []
        self._publisher: Publisher | None = None

    def attach(self, publisher: Publisher) -> None:
        """Publish through ``publisher`` from now on (at activate)."""
        self._publisher = publisher

    def detach(self) -> None:
        """Close the transport publisher (at deactivate); publishing is refused until attached again."""
        publisher, self._publisher = self._publisher, None
        if publisher is not None:
            publisher.close()

    def add_preprocessor(self, func: Callable[[Any], Any]) -> None:
        """Transform every value with ``func`` before it is published (in the order added)."""
        self._preprocessors.append(func)

    def publish(self, value: Any) -> None:
        """Apply pre-processors, validate against the topic type and send.

        An output of a step that a deactivate overtook is discarded and counted
        (``Component.discarded_outputs``), not an error: the component was asked to stop.
        """
        component = self._component
        publisher = self._publisher
        if publisher is None:
            if component._in_overtaken_step():
                component._discard_output(self.topic.name)
                return
            raise ComponentError(f"component {component.component_name!r}: output {self.topic.name!r} is not active")
        for func in self._preprocessors:
            value = func(value)
        try:
            publisher.publish(value)
        except TransportClosedError:
            if component._in_overtaken_step():
                component._discard_output(self.topic.name)
                return
            raise


class Component(HealthAndFallbacks, ComponentServices):
    """A processing unit with typed inputs and outputs, fired by a trigger.

    :param inputs: input topics (``Topic`` or ``FixedInput``).
    :param outputs: output topics.
    :param config: the component's config (deep-copied; defaults to the class's config).
    :param trigger: ``float`` Hz, an input ``Topic``, a list of input topics (any fires), an
        ``Event``, or None for server components (``run_type`` SERVER / ACTION_SERVER).
    :param component_name: unique name; also the namespace of its status topic and services.
    :param config_file: YAML / TOML / JSON file to load the config from (section = component name).
    :param run_type: override the run type derived from the trigger (e.g. ``"Server"``).
    """

    #: Config class used when none is given; a config passed in must be an instance of it.
    config_class: type[BaseComponentConfig] = BaseComponentConfig
    #: Accepted input / output types (see :mod:`agents_core.components.wiring`); None: anything.
    #: Subclasses set them on the class, or on the instance before ``super().__init__``.
    allowed_inputs: AllowedTypes | None = None
    allowed_outputs: AllowedTypes | None = None
    #: For ACTION_SERVER components: the action type (e.g. ``"VisionLanguageAction"``) served on
    #: :attr:`action_name` while active, each goal running :meth:`main_action_callback`.
    _action_type: str | None = None

    #: The positional and keyword arguments the component was constructed with.
    _init_arguments: tuple[tuple[Any, ...], dict[str, Any]]

    def __new__(cls, *args: Any, **kwargs: Any) -> Any:
        # The arguments the recipe built it with: a launcher with multiprocessing=True rebuilds
        # the component from them in its own process (see agents_core.processes.spec).
        instance = super().__new__(cls)
        instance._init_arguments = (args, dict(kwargs))
        return instance

    def __init__(
        self,
        inputs: Sequence[Topic] | None = None,
        outputs: Sequence[Topic] | None = None,
        config: BaseComponentConfig | None = None,
        trigger: TriggerType = 1.0,
        component_name: str = "component",
        *,
        config_file: str | Path | None = None,
        run_type: ComponentRunType | str | None = None,
        **kwargs: Any,
    ) -> None:
        if kwargs:
            raise ConfigError(f"component {component_name!r}: unexpected argument(s) {sorted(kwargs)}")
        self.component_name = validate_topic_name(component_name, "component")
        self.config = self._prepare_config(config, config_file)
        self._logger = logging.getLogger(f"agents_core.{self.component_name}")
        self._logger.setLevel(self.config.log_level.upper())

        self.inputs: list[Topic] = check_topic_list(self.component_name, inputs, "inputs")
        self.outputs: list[Topic] = check_topic_list(self.component_name, outputs, "outputs")
        validate_topics(self.component_name, type(self).__name__, self.inputs, self.allowed_inputs, "input")
        validate_topics(self.component_name, type(self).__name__, self.outputs, self.allowed_outputs, "output")

        self.run_type = resolve_run_type(self.component_name, trigger, run_type, self.inputs,
                                         type(self)._server_capable)
        self.trigger = trigger
        self.callbacks: dict[str, GenericCallback] = {t.name: callback_for(t) for t in self.inputs}
        self.trig_callbacks: dict[str, GenericCallback] = {}
        for t in trigger_topics(trigger):
            self.trig_callbacks[t.name] = self.callbacks.pop(t.name)
        self.publishers_dict: dict[str, ComponentPublisher] = {t.name: ComponentPublisher(t, self)
                                                               for t in self.outputs}
        self.status_topic = status_topic(self.component_name)

        self.events_actions: dict[Event, list[Action]] = {}
        self._fallbacks: dict[str, Fallback] = {}
        self._giveup_actions: list[Action] = []
        self._gave_up = False

        self._lifecycle = LifecycleMachine(self.component_name, on_failed=self._on_transition_failed,
                                           on_done=self._on_transition_done)
        self._health = HealthStatus.HEALTHY
        self._health_message = ""
        #: The one door between a Launcher (or a test) and this component's runtime.
        self.runtime = ComponentRuntime(self)
        self._transport: Transport | None = None
        self._presence: ComponentPresence | None = None
        self._services: list[ServiceServer] = []
        self._action_server: ActionServer | None = None
        self._subscriptions: list[Subscription] = []
        self._timers: list[PeriodicTimer] = []
        self._status_timer: PeriodicTimer | None = None
        self._worker: StepWorker | None = None
        self._failed_steps = 0
        # Set by a failed step (or a health change away from HEALTHY), cleared by the next good
        # one: the common path of a step checks one flag.
        self._recovering = False
        # Bumped by every deactivate: a step that started under an older epoch was overtaken by
        # it, and its outputs and failures are discarded (counted), never reported as failures.
        self._epoch = 0
        self._step_epoch: int | None = None
        self._accepting_steps = False
        self._discarded_outputs = 0
        self._overtaken_steps = 0
        # Set by hurry_shutdown() (a second Ctrl-C): stop waiting for a running step.
        self._hurry = threading.Event()

        for cb_name, cb in self.trig_callbacks.items():
            cb.on_callback_execute(self._make_topic_trigger(self._topic(cb_name)))

    # -- construction helpers ---------------------------------------------------------------

    def _prepare_config(self, config: BaseComponentConfig | None, config_file: str | Path | None) -> Any:
        if config is None:
            config = self.config_class()
        expected = type(self).config_class
        if not isinstance(config, expected):
            article = "an" if expected.__name__[0] in "AEIOU" else "a"
            raise ConfigError(f"component {self.component_name!r}: config must be {article} {expected.__name__}, "
                              f"got {type(config).__name__}")
        if config_file is not None:
            loaded = type(config).from_file(config_file, section=self.component_name)
            config = loaded
        # Each component gets its own copy: sharing one config object between components must not
        # let a parameter update on one change the other.
        return copy.deepcopy(config)

    @classmethod
    def _server_capable(cls) -> bool:
        """Whether this class may run with no trigger (servers answer requests instead)."""
        return False

    def _topic(self, name: str) -> Topic:
        for t in (*self.inputs, *self.outputs):
            if t.name == name:
                return t
        raise WiringError(f"component {self.component_name!r} has no topic {name!r}")

    # -- public info ------------------------------------------------------------------------

    @property
    def node_name(self) -> str:
        """Alias of :attr:`component_name` (the upstream name)."""
        return self.component_name

    @property
    def lifecycle_state(self) -> LifecycleState:
        """Current lifecycle state."""
        return self._state

    @property
    def health_status(self) -> HealthStatus:
        """Current health status."""
        return self._health

    def get_logger(self) -> logging.Logger:
        """The component's logger (``agents_core.<component_name>``)."""
        return self._logger

    def worker_statistics(self) -> WorkerStatistics:
        """Counters of the serial worker (submitted, executed, dropped steps, ...)."""
        if self._worker is None:
            return WorkerStatistics()
        return self._worker.statistics()

    @property
    def failed_steps(self) -> int:
        """How many steps raised (not counting steps overtaken by a deactivate)."""
        return self._failed_steps

    @property
    def discarded_outputs(self) -> int:
        """Outputs of steps overtaken by a deactivate, discarded instead of published."""
        return self._discarded_outputs

    @property
    def overtaken_steps(self) -> int:
        """Steps that were running when a deactivate came, whose results were discarded."""
        return self._overtaken_steps

    def input_statistics(self) -> dict[str, SubscriptionStatistics]:
        """Counters of each input subscription while active (delivered, dropped, decode errors, ...)."""
        return {sub.topic.name: sub.statistics() for sub in list(self._subscriptions)}

    @property
    def action_name(self) -> str:
        """The name goals are sent to, for an action-server component (default: the component name)."""
        return self.component_name

    def main_action_callback(self, goal_handle: GoalHandle) -> dict[str, Any]:
        """Run one goal (ACTION_SERVER components); returns the result dict. Runs on the goal's own thread."""
        raise NotImplementedError(f"{type(self).__name__} must implement main_action_callback()")

    def _accept_goal(self, goal: dict[str, Any]) -> bool:
        """Whether to accept a validated goal (default: yes)."""
        return True

    @property
    def transport(self) -> Transport:
        """The transport the component was launched on."""
        if self._transport is None:
            raise ComponentError(f"component {self.component_name!r} is not launched (add it to a Launcher)")
        return self._transport

    # -- processors -------------------------------------------------------------------------

    def add_publisher_preprocessor(self, topic: Topic | str, func: Callable[[Any], Any]) -> None:
        """Transform values published on output ``topic`` with ``func`` first."""
        name = topic.name if isinstance(topic, Topic) else topic
        if name not in self.publishers_dict:
            raise WiringError(f"component {self.component_name!r} has no output {name!r}")
        self.publishers_dict[name].add_preprocessor(func)

    def add_callback_postprocessor(self, topic: Topic | str, func: Callable[[Any], Any]) -> None:
        """Transform what ``get_output()`` returns for input ``topic`` with ``func``."""
        name = topic.name if isinstance(topic, Topic) else topic
        cb = self.callbacks.get(name) or self.trig_callbacks.get(name)
        if cb is None:
            raise WiringError(f"component {self.component_name!r} has no input {name!r}")
        cb.add_post_processor(func)

    # -- lifecycle --------------------------------------------------------------------------

    def _transition(self, name: str, body: Callable[[], None]) -> None:
        self._lifecycle.run(name, body)

    @property
    def _state(self) -> LifecycleState:
        return self._lifecycle.state

    def _on_transition_failed(self, name: str, exc: Exception) -> None:
        self._set_health(HealthStatus.COMPONENT_FAILURE, f"{name} failed: {exc}")

    def _on_transition_done(self, name: str, target: LifecycleState) -> None:
        self._logger.info("%s -> %s", name, target.value)
        self._report_status()

    def configure(self) -> None:
        """unconfigured -> inactive: connect clients, load models, warm up."""
        self._transition("configure", self._do_configure)

    def activate(self) -> None:
        """inactive -> active: create publishers and subscriptions, start the triggers."""
        self._transition("activate", self._do_activate)

    def deactivate(self) -> None:
        """active -> inactive: stop triggers and subscriptions; pending steps are discarded.

        A step running meanwhile may finish for up to ``config.step_finish_timeout`` seconds;
        its outputs are discarded and counted, and a failure it raises is not a component
        failure (no health change, no fallback).
        """
        self._transition("deactivate", self._do_deactivate)

    def cleanup(self) -> None:
        """inactive -> unconfigured: undo configure."""
        self._transition("cleanup", self._do_cleanup)

    def hurry_shutdown(self) -> None:
        """Stop waiting for a running step in deactivate and shutdown (what a second Ctrl-C asks)."""
        self._hurry.set()

    def shutdown(self) -> None:
        """any -> finalized: release everything (deactivating first if active)."""
        with self._lifecycle.lock:
            if self._state == LifecycleState.FINALIZED:
                return
            if self._state == LifecycleState.ACTIVE:
                self.deactivate()
            self._transition("shutdown", self._do_shutdown)

    def _do_configure(self) -> None:
        self.custom_on_configure()

    def _do_activate(self) -> None:
        transport = self.transport
        self._accepting_steps = True
        for name, pub in self.publishers_dict.items():
            pub.attach(transport.create_publisher(self._topic(name), owner=self.component_name))
        for t in self.inputs:
            if isinstance(t, FixedInput):
                continue
            cb = self.callbacks.get(t.name) or self.trig_callbacks[t.name]
            # Inline: the middleware's thread stores the value and enqueues the step on this
            # component's worker, whose bounded queue is then the only queue of the hop.
            self._subscriptions.append(transport.create_subscription(t, cb._receive, owner=self.component_name,
                                                                     inline=True))
        if self.run_type == ComponentRunType.TIMED:
            assert isinstance(self.trigger, int | float)
            self._timers.append(PeriodicTimer(float(self.trigger), self._submit_timed_step,
                                              f"{self.component_name}:trigger"))
        elif isinstance(self.trigger, Event):
            self.trigger.add_listener(self._on_trigger_event)
        self._status_timer = PeriodicTimer(self.config.status_rate, self._report_status,
                                           f"{self.component_name}:status")
        self.custom_on_activate()
        self.runtime.open_action_server()

    def _do_deactivate(self) -> None:
        # First of all: no new step starts, and the running one (if any) is overtaken.
        self._accepting_steps = False
        self._epoch += 1
        self.runtime.close_action_server()
        self.custom_on_deactivate()
        if isinstance(self.trigger, Event):
            self.trigger.remove_listener(self._on_trigger_event)
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
            if not worker.on_worker_thread and not worker.wait_step_done(self.config.step_finish_timeout,
                                                                          self._hurry):
                self._logger.info("a step is still running after %.1f s; its outputs will be discarded",
                                  self.config.step_finish_timeout)
        for pub in self.publishers_dict.values():
            pub.detach()

    def _do_cleanup(self) -> None:
        self.custom_on_cleanup()

    def _do_shutdown(self) -> None:
        self.custom_on_shutdown()
        if self._worker is not None:
            self._worker.stop(timeout=max(self.config.step_finish_timeout, 1.0), abort=self._hurry)
        for srv in self._services:
            srv.close()
        self._services.clear()
        if self._presence is not None:
            self._presence.close()
            self._presence = None

    # Hooks for subclasses (upstream names); each runs inside its transition.
    def custom_on_configure(self) -> None:
        """Extra work at configure (connect clients, load models)."""

    def custom_on_activate(self) -> None:
        """Extra work at activate."""

    def custom_on_deactivate(self) -> None:
        """Extra work at deactivate."""

    def custom_on_cleanup(self) -> None:
        """Extra work at cleanup."""

    def custom_on_shutdown(self) -> None:
        """Extra work at shutdown."""

    # -- triggers and steps -----------------------------------------------------------------

    def _make_topic_trigger(self, topic: Topic) -> Callable[[Any], None]:
        def fire(value: Any) -> None:
            self._submit_step({"topic": topic}, snapshot=(topic.name, value))

        return fire

    def _submit_timed_step(self) -> None:
        self._submit_step({})

    def _on_trigger_event(self, event: Event, values: Mapping[str, Any]) -> None:
        self._submit_step({"event": event})

    def _submit_step(self, kwargs: dict[str, Any], snapshot: tuple[str, Any] | None = None) -> None:
        if self._worker is None:
            return
        if self._state != LifecycleState.ACTIVE or not self._accepting_steps:
            # Arrived while (de)activating: discarded, and counted as such.
            self._worker.count_discarded()
            return
        epoch = self._epoch
        self._worker.submit_step(lambda: self._run_step(kwargs, snapshot, epoch))

    def _in_overtaken_step(self) -> bool:
        """True on the worker thread, in a step that a deactivate has overtaken."""
        return (self._worker is not None and self._worker.on_worker_thread and self._step_epoch is not None
                and self._step_epoch != self._epoch)

    def _discard_output(self, topic_name: str) -> None:
        self._discarded_outputs += 1
        self._logger.debug("discarded an output on %r: the component was deactivated during the step", topic_name)

    def _run_step(self, kwargs: dict[str, Any], snapshot: tuple[str, Any] | None, epoch: int) -> None:
        if self._state != LifecycleState.ACTIVE or epoch != self._epoch:
            return
        cb = None
        if snapshot is not None:
            cb = self.trig_callbacks[snapshot[0]]
            cb._begin_step(snapshot[1])
        self._step_epoch = epoch
        try:
            self._execution_step(**kwargs)
        except Exception as exc:
            if epoch != self._epoch:
                # Deactivated under the step: whatever failed (a closed publisher, a cancelled
                # stream) failed because the component was asked to stop.
                self._overtaken_steps += 1
                self._logger.debug("a step overtaken by deactivate ended with %s: %s", type(exc).__name__, exc)
            elif isinstance(exc, AlgorithmFailure):
                self._step_failed(HealthStatus.ALGORITHM_FAILURE, exc)
            elif isinstance(exc, TransportError):
                self._step_failed(HealthStatus.SYSTEM_FAILURE, exc)
            else:
                self._step_failed(HealthStatus.COMPONENT_FAILURE, exc)
        else:
            if epoch != self._epoch:
                self._overtaken_steps += 1
                return
            if self._recovering:
                # The first good step after failures: healthy again, fallbacks start over.
                self._recovering = False
                if self._health != HealthStatus.HEALTHY:
                    self._set_health(HealthStatus.HEALTHY, "")
                for f in self._fallbacks.values():
                    f.reset()
                self._gave_up = False
        finally:
            self._step_epoch = None
            if cb is not None:
                cb._end_step()

    def _execution_step(self, **kwargs: Any) -> None:
        """One unit of work; called on the component's worker each time the trigger fires."""
        raise NotImplementedError(f"{type(self).__name__} must implement _execution_step()")

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.component_name!r} {self._state.value}>"
