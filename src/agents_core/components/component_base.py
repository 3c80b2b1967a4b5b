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
import math
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..actions import ACTION_MARK, Action, Fallback
from ..callbacks import GenericCallback, callback_for
from ..config import BaseComponentConfig, configure_time_fields
from ..errors import (
    AlgorithmFailure,
    ComponentError,
    ConfigError,
    LifecycleError,
    RequestTimeoutError,
    TransportClosedError,
    TransportError,
    WiringError,
)
from ..events import Event
from ..status import TRANSITIONS, HealthStatus, LifecycleState
from ..supported_types import SupportedType
from ..topics import FixedInput, Topic, validate_topic_name
from ..transport.core import status_topic
from ..transport.delivery import SubscriptionStatistics
from ..transport.requests import check_timeout, request_deadline
from .run_type import ComponentRunType
from .worker import MAX_TIMER_RATE_HZ, PeriodicTimer, StepWorker, WorkerStatistics

if TYPE_CHECKING:
    from ..transport.contract import ComponentPresence, Publisher, ServiceServer, Subscription, Transport

__all__ = ["Component", "ComponentPublisher"]

AllowedTypes = Mapping[str, Sequence[type[SupportedType] | Sequence[type[SupportedType]]]]
TriggerType = Topic | Sequence[Topic] | float | int | Event | None


class ComponentPublisher:
    """A component's publisher for one output topic, applying its pre-processors before sending."""

    def __init__(self, topic: Topic, component: Component) -> None:
        self.topic = topic
        self._component = component
        self._preprocessors: list[Callable[[Any], Any]] = []
        self._publisher: Publisher | None = None

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


def _type_label(entry: type[SupportedType] | Sequence[type[SupportedType]]) -> str:
    if isinstance(entry, type):
        return entry.type_name()
    return " or ".join(t.type_name() for t in entry)


def _matches(msg_type: type[SupportedType], entry: type[SupportedType] | Sequence[type[SupportedType]]) -> bool:
    options = [entry] if isinstance(entry, type) else list(entry)
    return any(issubclass(msg_type, t) for t in options)


class Component:
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

    #: Config class used when none is given.
    config_class: type[BaseComponentConfig] = BaseComponentConfig

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

        self.inputs: list[Topic] = self._check_topic_list(inputs, "inputs")
        self.outputs: list[Topic] = self._check_topic_list(outputs, "outputs")
        for t in self.outputs:
            if isinstance(t, FixedInput):
                raise WiringError(f"component {self.component_name!r}: FixedInput {t.name!r} cannot be an output")
        if not hasattr(self, "allowed_inputs"):
            self.allowed_inputs: AllowedTypes | None = None
        if not hasattr(self, "allowed_outputs"):
            self.allowed_outputs: AllowedTypes | None = None
        self._validate_topics(self.inputs, self.allowed_inputs, "input")
        self._validate_topics(self.outputs, self.allowed_outputs, "output")

        self.run_type = self._resolve_run_type(trigger, run_type)
        self.trigger = trigger
        self.callbacks: dict[str, GenericCallback] = {t.name: callback_for(t) for t in self.inputs}
        self.trig_callbacks: dict[str, GenericCallback] = {}
        for t in self._trigger_topics():
            self.trig_callbacks[t.name] = self.callbacks.pop(t.name)
        self.publishers_dict: dict[str, ComponentPublisher] = {t.name: ComponentPublisher(t, self)
                                                               for t in self.outputs}
        self.status_topic = status_topic(self.component_name)

        self.events_actions: dict[Event, list[Action]] = {}
        self._fallbacks: dict[str, Fallback] = {}
        self._giveup_actions: list[Action] = []
        self._gave_up = False

        self._state = LifecycleState.UNCONFIGURED
        self._health = HealthStatus.HEALTHY
        self._health_message = ""
        self._transition_lock = threading.RLock()
        self._transport: Transport | None = None
        self._presence: ComponentPresence | None = None
        self._services: list[ServiceServer] = []
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
        if not isinstance(config, BaseComponentConfig):
            raise ConfigError(f"component {self.component_name!r}: config must be a BaseComponentConfig, "
                              f"got {type(config).__name__}")
        if config_file is not None:
            loaded = type(config).from_file(config_file, section=self.component_name)
            config = loaded
        # Each component gets its own copy: sharing one config object between components must not
        # let a parameter update on one change the other.
        return copy.deepcopy(config)

    def _check_topic_list(self, topics: Sequence[Topic] | None, what: str) -> list[Topic]:
        if topics is None:
            return []
        if isinstance(topics, Topic) or not isinstance(topics, Sequence):
            raise WiringError(f"component {self.component_name!r}: {what} must be a list of Topic")
        out = list(topics)
        seen: set[str] = set()
        for t in out:
            if not isinstance(t, Topic):
                raise WiringError(f"component {self.component_name!r}: {what} has a {type(t).__name__}, not a Topic")
            if t.name in seen:
                raise WiringError(f"component {self.component_name!r}: topic {t.name!r} is listed twice in {what}")
            seen.add(t.name)
        return out

    def _validate_topics(self, topics: list[Topic], allowed: AllowedTypes | None, kind: str) -> None:
        if allowed is None:
            return
        unknown_keys = set(allowed) - {"Required", "Optional"}
        if unknown_keys:
            raise ConfigError(f"{type(self).__name__}.allowed_{kind}s has unknown keys {sorted(unknown_keys)}")
        required = list(allowed.get("Required", []))
        optional = list(allowed.get("Optional", []))
        for entry in required:
            if not any(_matches(t.msg_type, entry) for t in topics):
                raise WiringError(
                    f"component {self.component_name!r} needs an {kind} topic of type {_type_label(entry)}; "
                    f"got {[f'{t.name}: {t.type_name}' for t in topics] or 'none'}"
                )
        for t in topics:
            if not any(_matches(t.msg_type, e) for e in required + optional):
                accepted = ", ".join(_type_label(e) for e in required + optional)
                raise WiringError(
                    f"component {self.component_name!r}: {kind} topic {t.name!r} has type {t.type_name}, "
                    f"which it does not accept (accepted: {accepted})"
                )

    def _resolve_run_type(self, trigger: TriggerType, run_type: ComponentRunType | str | None) -> ComponentRunType:
        name = self.component_name
        input_names = {t.name for t in self.inputs}
        if isinstance(trigger, bool):
            raise WiringError(f"component {name!r}: trigger cannot be a bool")
        if isinstance(trigger, int | float):
            if not math.isfinite(trigger) or not 0 < trigger <= MAX_TIMER_RATE_HZ:
                raise WiringError(f"component {name!r}: a timed trigger needs a rate > 0 Hz (finite, at most "
                                  f"{MAX_TIMER_RATE_HZ:g} Hz), got {trigger}")
            derived = ComponentRunType.TIMED
        elif isinstance(trigger, Topic):
            if trigger.name not in input_names:
                raise WiringError(f"component {name!r}: trigger topic {trigger.name!r} is not one of its inputs "
                                  f"{sorted(input_names)}")
            if isinstance(trigger, FixedInput):
                raise WiringError(f"component {name!r}: FixedInput {trigger.name!r} never changes; it cannot trigger")
            derived = ComponentRunType.EVENT
        elif isinstance(trigger, Event):
            derived = ComponentRunType.EVENT
        elif trigger is None:
            derived = ComponentRunType.SERVER
        elif isinstance(trigger, list | tuple):
            if not trigger:
                raise WiringError(f"component {name!r}: an empty list of trigger topics never fires")
            for t in trigger:
                if not isinstance(t, Topic) or t.name not in input_names:
                    raise WiringError(f"component {name!r}: trigger {t!r} is not one of its inputs "
                                      f"{sorted(input_names)}")
            derived = ComponentRunType.EVENT
        else:
            raise WiringError(f"component {name!r}: trigger must be a rate (Hz), a Topic, a list of Topics, "
                              f"an Event or None; got {type(trigger).__name__}")
        if run_type is not None:
            chosen = ComponentRunType.parse(run_type)
            if trigger is None and chosen not in (ComponentRunType.SERVER, ComponentRunType.ACTION_SERVER):
                raise WiringError(f"component {name!r}: trigger=None is only valid for Server or ActionServer "
                                  f"components, not {chosen.value}")
            return chosen
        if trigger is None and not type(self)._server_capable():
            raise WiringError(f"component {name!r}: trigger=None is only valid for server components "
                              "(pass run_type='Server' or give a rate, a topic or an event)")
        return derived

    @classmethod
    def _server_capable(cls) -> bool:
        """Whether this class may run with no trigger (servers answer requests instead)."""
        return False

    def _trigger_topics(self) -> list[Topic]:
        if isinstance(self.trigger, Topic):
            return [self.trigger]
        if isinstance(self.trigger, list | tuple):
            return list(self.trigger)
        return []

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

    # -- fallbacks --------------------------------------------------------------------------

    def on_fail(self, action: Action | Sequence[Action], max_retries: int | None = None) -> None:
        """Run ``action`` (or each in turn) on any failure without a more specific fallback."""
        self._fallbacks["any"] = Fallback(action, max_retries)

    on_any_fail = on_fail

    def on_component_fail(self, action: Action | Sequence[Action], max_retries: int | None = None) -> None:
        """Run ``action`` when a step fails with a component failure (e.g. the model client is down)."""
        self._fallbacks[HealthStatus.COMPONENT_FAILURE.name] = Fallback(action, max_retries)

    def on_algorithm_fail(self, action: Action | Sequence[Action], max_retries: int | None = None) -> None:
        """Run ``action`` when a step raises :class:`~agents_core.errors.AlgorithmFailure`."""
        self._fallbacks[HealthStatus.ALGORITHM_FAILURE.name] = Fallback(action, max_retries)

    def on_system_fail(self, action: Action | Sequence[Action], max_retries: int | None = None) -> None:
        """Run ``action`` when the transport fails under a step."""
        self._fallbacks[HealthStatus.SYSTEM_FAILURE.name] = Fallback(action, max_retries)

    def on_giveup(self, action: Action | Sequence[Action]) -> None:
        """Run ``action`` once when a fallback has used up all its retries."""
        self._giveup_actions = [action] if isinstance(action, Action) else list(action)

    # -- lifecycle --------------------------------------------------------------------------

    def _transition(self, name: str, body: Callable[[], None]) -> None:
        with self._transition_lock:
            allowed_from, target = TRANSITIONS[name]
            if self._state not in allowed_from:
                raise LifecycleError(f"component {self.component_name!r}: cannot {name} from state "
                                     f"{self._state.value!r}")
            try:
                body()
            except Exception as exc:
                self._state = LifecycleState.ERROR
                self._set_health(HealthStatus.COMPONENT_FAILURE, f"{name} failed: {exc}")
                if isinstance(exc, LifecycleError | ConfigError):
                    raise
                raise LifecycleError(f"component {self.component_name!r}: {name} failed: {exc}") from exc
            self._state = target
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
        with self._transition_lock:
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
            pub._publisher = transport.create_publisher(self._topic(name), owner=self.component_name)
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

    def _do_deactivate(self) -> None:
        # First of all: no new step starts, and the running one (if any) is overtaken.
        self._accepting_steps = False
        self._epoch += 1
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
            if pub._publisher is not None:
                pub._publisher.close()
                pub._publisher = None

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

    # -- binding to a transport (called by the Launcher) -------------------------------------

    def _bind(self, transport: Transport) -> None:
        """Attach to ``transport``: declare presence, services and status publisher, start the worker."""
        if self._transport is not None:
            raise ComponentError(f"component {self.component_name!r} is already launched")
        if self.run_type == ComponentRunType.ACTION_SERVER and not transport.capabilities.actions:
            raise WiringError(f"component {self.component_name!r} runs as an action server, but the "
                              f"{transport.name!r} transport has no long-running goals (actions)")
        self._transport = transport
        self._worker = StepWorker(self.component_name, self.config.execution_queue_depth,
                                  self.config.queue_full_policy)
        # The presence publishes the status topic too: one path for the component's state.
        self._presence = transport.declare_component(self.component_name, on_transition=self._external_transition,
                                                     pending=lambda: self.worker_statistics().pending)
        prefix = self.component_name
        self._services.append(transport.create_service(f"{prefix}/execute_method", self._serve_execute_method,
                                                       owner=self.component_name))
        self._services.append(transport.create_service(f"{prefix}/set_param", self._serve_set_param,
                                                       owner=self.component_name))
        self._report_status()

    def _external_transition(self, transition: str) -> bool:
        """Run a transition asked from outside (lifecycle service, queryable); never raises."""
        method = {"configure": self.configure, "activate": self.activate, "deactivate": self.deactivate,
                  "cleanup": self.cleanup, "shutdown": self.shutdown}.get(transition)
        if method is None:
            self._logger.warning("unknown lifecycle transition %r requested", transition)
            return False
        try:
            method()
        except Exception as exc:
            self._logger.warning("transition %r requested from outside failed: %s", transition, exc)
            return False
        return True

    # -- services ---------------------------------------------------------------------------

    def available_actions(self) -> dict[str, dict[str, Any]]:
        """The methods marked with ``@component_action`` and their OpenAI-style descriptions."""
        found: dict[str, dict[str, Any]] = {}
        for name in dir(type(self)):
            attr = getattr(type(self), name, None)
            description = getattr(attr, ACTION_MARK, None)
            if description is not None:
                found[name] = description
        return found

    def _serve_execute_method(self, request: dict[str, Any]) -> dict[str, Any]:
        method_name = request.get("method")
        actions = self.available_actions()
        if method_name not in actions:
            raise ComponentError(f"component {self.component_name!r} has no action {method_name!r}; "
                                 f"available: {sorted(actions)}")
        args = request.get("args", [])
        kwargs = request.get("kwargs", {})
        if not isinstance(args, list) or not isinstance(kwargs, dict):
            raise ConfigError("execute_method needs 'args' as a list and 'kwargs' as a mapping")
        method = getattr(self, str(method_name))
        timeout = check_timeout(request.get("timeout", 30.0), f"component {self.component_name!r}: execute_method")
        result = self.run_on_worker(lambda: method(*args, **kwargs), timeout=timeout)
        return {"result": result if isinstance(result, str | int | float | bool | type(None) | list | dict)
                else repr(result)}

    def _serve_set_param(self, request: dict[str, Any]) -> dict[str, Any]:
        params = request.get("params")
        if params is None and "name" in request:
            params = {request["name"]: request.get("value")}
        if not isinstance(params, dict) or not params:
            raise ConfigError("set_param needs {'name': ..., 'value': ...} or {'params': {...}}")
        self.set_params(**params)
        return {"ok": True, "params": sorted(params)}

    def set_params(self, **params: Any) -> None:
        """Change config fields of a running component, validated, applied at once.

        Live settings (``execution_queue_depth``, ``queue_full_policy``, ``log_level``,
        ``status_rate`` and what the component reads at each step) take effect immediately. Fields
        used only at configure (model files, local model settings, ...) are refused with
        :class:`~agents_core.errors.ConfigError` unless the component is unconfigured. An invalid
        value changes nothing.
        """
        at_configure = sorted(set(params) & configure_time_fields(self.config))
        if at_configure and self._state != LifecycleState.UNCONFIGURED:
            raise ConfigError(f"component {self.component_name!r}: {at_configure} apply at configure only; "
                              "deactivate and clean up the component, set them, then configure it again")
        self.run_on_worker(lambda: self._apply_params(params), timeout=10.0)

    def _apply_params(self, params: dict[str, Any]) -> None:
        self.config.update(**params)
        changed = set(params)
        if "log_level" in changed:
            self._logger.setLevel(self.config.log_level.upper())
        if self._worker is not None and changed & {"execution_queue_depth", "queue_full_policy"}:
            self._worker.set_queue(self.config.execution_queue_depth, self.config.queue_full_policy)
        if "status_rate" in changed and self._status_timer is not None:
            self._status_timer.stop()
            self._status_timer = PeriodicTimer(self.config.status_rate, self._report_status,
                                               f"{self.component_name}:status")

    def run_on_worker(self, func: Callable[[], Any], timeout: float = 30.0) -> Any:
        """Run ``func`` on the component's worker (between steps) and return its result.

        Waits at most ``timeout`` s, less when serving a request whose caller waits less; an
        item whose wait expired before it started is never run (``RequestTimeoutError``).
        """
        if self._worker is None or self._worker.on_worker_thread:
            return func()
        timeout = check_timeout(timeout, f"component {self.component_name!r}: run_on_worker")
        deadline = time.monotonic() + timeout
        caller_deadline = request_deadline()
        if caller_deadline is not None:
            deadline = min(deadline, caller_deadline)
        future = self._worker.submit_control(func, deadline=deadline)
        try:
            return future.result(timeout=max(0.0, deadline - time.monotonic()))
        except TimeoutError:
            if future.cancel():
                raise RequestTimeoutError(f"component {self.component_name!r}: the worker did not get to the "
                                          f"request within {timeout:g} s (busy with a step?)") from None
            if not future.done():
                raise RequestTimeoutError(f"component {self.component_name!r}: the request did not finish within "
                                          f"{timeout:g} s") from None
            raise

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

    def _step_failed(self, status: HealthStatus, exc: Exception) -> None:
        self._failed_steps += 1
        self._recovering = True
        self._logger.error("step failed (%s): %s: %s", status.name, type(exc).__name__, exc,
                           exc_info=self._logger.isEnabledFor(logging.DEBUG))
        self._set_health(status, f"{type(exc).__name__}: {exc}")
        fallback = self._fallbacks.get(status.name) or self._fallbacks.get("any")
        if fallback is None:
            return
        action = fallback.next_action()
        if action is None:
            if not self._gave_up:
                self._gave_up = True
                self._logger.error("fallbacks exhausted; giving up")
                for giveup in self._giveup_actions:
                    self._run_action(giveup, {})
            return
        self._logger.info("running fallback %s", action.name)
        self._run_action(action, {})

    def _run_action(self, action: Action, values: Mapping[str, Any]) -> Any:
        try:
            return action(values)
        except Exception:
            self._logger.exception("action %s failed", action.name)
            return None

    # -- health -----------------------------------------------------------------------------

    def _set_health(self, status: HealthStatus, message: str) -> None:
        if status != HealthStatus.HEALTHY:
            self._recovering = True
        changed = status != self._health
        self._health = status
        self._health_message = message
        if changed:
            self._report_status()

    def _report_status(self) -> None:
        presence = self._presence
        if presence is None:
            return
        try:
            presence.update(self._state, self._health, self._health_message)
        except TransportError as exc:
            self._logger.debug("status not published: %s", exc)

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.component_name!r} {self._state.value}>"
