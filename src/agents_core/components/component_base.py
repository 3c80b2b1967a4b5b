"""``Component``: the declaration of a processing unit — inputs, outputs, trigger, config, the step.

Subclass it for processing that needs no model (subclass
:class:`~agents_core.components.model_component.ModelComponent` otherwise) and implement
``_execution_step(**kwargs)``. Declare ``self.allowed_inputs`` / ``self.allowed_outputs``
before calling ``super().__init__``::

    self.allowed_inputs = {"Required": [Image, [String, Audio]], "Optional": [CompressedImage]}

Each ``Required`` entry needs at least one topic of that type (a list entry: of any of its
types); every topic given must match some entry; subclasses of a listed type match it.

What runs the component (its transport, serial worker, lifecycle, health and fallbacks,
services, timers) is its :attr:`Component.runtime`, a
:class:`~agents_core.runtime.component_runtime.ComponentRuntime`: the component's steps,
actions and fallbacks all run on that runtime's serial worker (see
:mod:`agents_core.runtime.worker`).
"""

from __future__ import annotations

import copy
import logging
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..actions import ACTION_MARK, GUARD_MARK, Action
from ..callbacks import GenericCallback, callback_for
from ..config import BaseComponentConfig
from ..declarations.setup_calls import constructor, setup_method, start_recording
from ..errors import ConfigError, WiringError
from ..events import Event
from ..runtime.component_runtime import ComponentRuntime
from ..runtime.health import ANY_FAILURE
from ..runtime.run_type import ComponentRunType
from ..runtime.worker import WorkerStatistics
from ..status import HealthStatus, LifecycleState
from ..topics import Topic, validate_topic_name
from ..transport.core import status_topic
from ..transport.delivery import SubscriptionStatistics
from .publisher import ComponentPublisher
from .wiring import AllowedTypes, TriggerType, check_topic_list, resolve_run_type, trigger_topics, validate_topics

if TYPE_CHECKING:
    from ..transport.contract import Transport
    from ..transport.goals import GoalHandle

__all__ = ["AllowedTypes", "Component", "ComponentPublisher", "TriggerType", "carried_state"]


def carried_state(component: Component) -> dict[str, int]:
    """What a component holds beyond its attributes that a process must rebuild through its methods (counts)."""
    publishers = getattr(component, "publishers_dict", None) or {}
    callbacks = [*(getattr(component, "callbacks", None) or {}).values(),
                 *(getattr(component, "trig_callbacks", None) or {}).values()]
    return {"publisher pre-processors": sum(len(p._preprocessors) for p in publishers.values()),
            "callback post-processors": sum(len(cb._postprocessors) for cb in callbacks)}


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
        # the component from them in its own process (see agents_core.launch.spec).
        instance = super().__new__(cls)
        instance._init_arguments = (args, dict(kwargs))
        # The setup calls made and attributes assigned after construction (agents_core.declarations.setup_calls).
        start_recording(instance, carried_state)
        return instance

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        # Setup calls a constructor makes are not recorded: the component's process makes them again.
        if "__init__" in cls.__dict__:
            cls.__init__ = constructor(cls.__dict__["__init__"])  # type: ignore[method-assign]

    @constructor
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
        self._validate_topics()

        self.run_type = resolve_run_type(self.component_name, trigger, run_type, self.inputs,
                                         type(self)._server_capable)
        self.trigger = trigger
        self.callbacks: dict[str, GenericCallback] = {t.name: callback_for(t) for t in self.inputs}
        self.trig_callbacks: dict[str, GenericCallback] = {}
        for t in trigger_topics(trigger):
            self.trig_callbacks[t.name] = self.callbacks.pop(t.name)
        self.status_topic = status_topic(self.component_name)
        self.events_actions: dict[Event, list[Action]] = {}
        #: What runs this component: transport, worker, lifecycle, health and fallbacks, services.
        #: The one door between a Launcher (or a test) and the running component.
        self.runtime = ComponentRuntime(self)
        self.publishers_dict: dict[str, ComponentPublisher] = {
            t.name: ComponentPublisher(t, self.component_name, self.runtime) for t in self.outputs}
        self._wired_trigger_callbacks: set[str] = set()

    def _validate_topics(self) -> None:
        """Check the inputs and outputs against ``allowed_inputs`` / ``allowed_outputs`` (called by ``__init__``).

        Every topic's type must match an entry (subclasses match), and every ``Required`` entry
        needs a topic. Raises :class:`~agents_core.errors.WiringError` naming the component and topic.
        A subclass may override it to check more (call ``super()._validate_topics()``).
        """
        validate_topics(self.component_name, type(self).__name__, self.inputs, self.allowed_inputs, "input")
        validate_topics(self.component_name, type(self).__name__, self.outputs, self.allowed_outputs, "output")

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
        return self.runtime.state

    @property
    def health_status(self) -> HealthStatus:
        """Current health status."""
        return self.runtime.health.status

    @property
    def health_message(self) -> str:
        """Why the component is not healthy (empty when it is)."""
        return self.runtime.health.message

    def get_logger(self) -> logging.Logger:
        """The component's logger (``agents_core.<component_name>``)."""
        return self._logger

    def worker_statistics(self) -> WorkerStatistics:
        """Counters of the serial worker (submitted, executed, dropped steps, ...)."""
        return self.runtime.worker_statistics()

    @property
    def failed_steps(self) -> int:
        """How many steps raised (not counting steps overtaken by a deactivate)."""
        return self.runtime.health.failed_steps

    @property
    def discarded_outputs(self) -> int:
        """Outputs of steps overtaken by a deactivate, discarded instead of published."""
        return self.runtime.discarded_outputs

    @property
    def skipped_outputs(self) -> int:
        """Outputs not published because a publisher pre-processor returned None ("nothing to publish")."""
        return sum(pub.skipped_outputs for pub in self.publishers_dict.values())

    @property
    def overtaken_steps(self) -> int:
        """Steps that were running when a deactivate came, whose results were discarded."""
        return self.runtime.overtaken_steps

    def input_statistics(self) -> dict[str, SubscriptionStatistics]:
        """Counters of each input subscription while active (delivered, dropped, decode errors, ...)."""
        return self.runtime.input_statistics()

    @property
    def transport(self) -> Transport:
        """The transport the component was launched on."""
        return self.runtime.transport

    def available_actions(self) -> dict[str, dict[str, Any]]:
        """The methods marked with ``@component_action`` and their OpenAI-style descriptions."""
        found: dict[str, dict[str, Any]] = {}
        for name in dir(type(self)):
            attr = getattr(type(self), name, None)
            description = getattr(attr, ACTION_MARK, None)
            if description is not None:
                found[name] = description
        return found

    def action_guardrails(self) -> dict[str, dict[str, Any]]:
        """The guardrails of each guarded action (:mod:`agents_core.guardrails`), as JSON."""
        found: dict[str, dict[str, Any]] = {}
        for name in self.available_actions():
            guard = getattr(getattr(type(self), name, None), GUARD_MARK, None)
            if guard is not None and guard.active:
                found[name] = guard.describe()
        return found

    def component_description(self) -> dict[str, Any]:
        """What ``<name>/describe`` answers: name, type, run type, state, health, inputs, outputs, actions
        (and ``action_type`` for an action server)."""
        description: dict[str, Any] = {
            "name": self.component_name,
            "component_type": type(self).__name__,
            "run_type": self.run_type.value,
            "state": self.runtime.state.value,
            "health": self.runtime.health.status.name,
            "inputs": [{"name": t.name, "msg_type": t.type_name} for t in self.inputs],
            "outputs": [{"name": t.name, "msg_type": t.type_name} for t in self.outputs],
            "actions": self.available_actions(),
        }
        guarded = self.action_guardrails()
        if guarded:
            description["guardrails"] = guarded
        if self.run_type == ComponentRunType.ACTION_SERVER and self._action_type is not None:
            description["action_type"] = self._action_type
        return description

    # -- goals (ACTION_SERVER components) ---------------------------------------------------

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

    # -- processors -------------------------------------------------------------------------

    @setup_method
    def add_publisher_preprocessor(self, topic: Topic | str, func: Callable[[Any], Any]) -> None:
        """Transform values published on output ``topic`` with ``func`` first.

        ``func`` returning None means "nothing to publish" this time: the value is skipped and
        counted (:attr:`skipped_outputs`), not an error.
        """
        name = topic.name if isinstance(topic, Topic) else topic
        if name not in self.publishers_dict:
            raise WiringError(f"component {self.component_name!r} has no output {name!r}")
        self.publishers_dict[name].add_preprocessor(func)

    @setup_method
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
        self.runtime.health.set_fallback(ANY_FAILURE, action, max_retries)

    on_any_fail = on_fail

    def on_component_fail(self, action: Action | Sequence[Action], max_retries: int | None = None) -> None:
        """Run ``action`` when a step fails with a component failure (e.g. the model client is down)."""
        self.runtime.health.set_fallback(HealthStatus.COMPONENT_FAILURE.name, action, max_retries)

    def on_algorithm_fail(self, action: Action | Sequence[Action], max_retries: int | None = None) -> None:
        """Run ``action`` when a step raises :class:`~agents_core.errors.AlgorithmFailure`."""
        self.runtime.health.set_fallback(HealthStatus.ALGORITHM_FAILURE.name, action, max_retries)

    def on_system_fail(self, action: Action | Sequence[Action], max_retries: int | None = None) -> None:
        """Run ``action`` when the transport fails under a step."""
        self.runtime.health.set_fallback(HealthStatus.SYSTEM_FAILURE.name, action, max_retries)

    def on_giveup(self, action: Action | Sequence[Action], max_retries: int | None = None) -> None:
        """Run ``action`` once when a fallback has used up all its retries.

        ``max_retries``: how many times an action that raises is tried (default once).
        """
        self.runtime.health.set_giveup(action, max_retries)

    # -- lifecycle --------------------------------------------------------------------------

    def configure(self) -> None:
        """unconfigured -> inactive: connect clients, load models, warm up."""
        self.runtime.transition("configure")

    def activate(self) -> None:
        """inactive -> active: create publishers and subscriptions, start the triggers."""
        self.runtime.transition("activate")

    def deactivate(self) -> None:
        """active -> inactive: stop triggers and subscriptions; pending steps are discarded.

        A step running meanwhile may finish for up to ``config.step_finish_timeout`` seconds;
        its outputs are discarded and counted, and a failure it raises is not a component
        failure (no health change, no fallback).
        """
        self.runtime.transition("deactivate")

    def cleanup(self) -> None:
        """inactive -> unconfigured: undo configure."""
        self.runtime.transition("cleanup")

    def shutdown(self) -> None:
        """any -> finalized: release everything (deactivating first if active)."""
        self.runtime.shutdown()

    def restart(self) -> None:
        """Bring the component back to active, from whatever state it is in (upstream's ``restart``).

        active: deactivate, then activate; inactive: activate; unconfigured: configure and
        activate; error: clean up, configure and activate. A finalized component cannot restart
        (:class:`~agents_core.errors.LifecycleError`).
        """
        self.runtime.restart()

    def stop(self) -> None:
        """Stop working, staying configured: deactivate when active (upstream's ``stop``); else nothing."""
        self.runtime.stop()

    def broadcast_status(self) -> None:
        """Publish the lifecycle state and health now on ``<name>/status`` (upstream's ``broadcast_status``)."""
        self.runtime.report_status()

    def hurry_shutdown(self) -> None:
        """Stop waiting for a running step in deactivate and shutdown (what a second Ctrl-C asks)."""
        self.runtime.hurry()

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

    # -- live settings and work between steps -----------------------------------------------

    def set_params(self, **params: Any) -> None:
        """Change config fields of a running component, validated, applied at once.

        Live settings (``execution_queue_depth``, ``queue_full_policy``, ``log_level``,
        ``status_rate`` and what the component reads at each step) take effect immediately. Fields
        used only at configure (model files, local model settings, ...) are refused with
        :class:`~agents_core.errors.ConfigError` unless the component is unconfigured. An invalid
        value changes nothing.
        """
        self.runtime.set_params(params)

    def run_on_worker(self, func: Callable[[], Any], timeout: float = 30.0) -> Any:
        """Run ``func`` on the component's worker (between steps) and return its result.

        Waits at most ``timeout`` s, less when serving a request whose caller waits less; an
        item whose wait expired before it started is never run (``RequestTimeoutError``).
        """
        return self.runtime.run_on_worker(func, timeout)

    # -- triggers and steps -----------------------------------------------------------------

    def activate_all_triggers(self) -> None:
        """Start what fires ``_execution_step``: called at activate, after the inputs are subscribed.

        Wires each trigger topic's callback to a step (``on_callback_execute``, once per callback),
        and starts the timer (a float trigger) or listens to the trigger ``Event``. Deactivate stops
        them. A subclass overriding it calls ``super().activate_all_triggers()``.
        """
        for cb_name, cb in self.trig_callbacks.items():
            if cb_name not in self._wired_trigger_callbacks:
                cb.on_callback_execute(self._make_topic_trigger(self._topic(cb_name)))
                self._wired_trigger_callbacks.add(cb_name)
        self.runtime.start_triggers()

    def _make_topic_trigger(self, topic: Topic) -> Callable[[Any], None]:
        """What a value arriving on trigger ``topic`` does (by default: queue one step with it)."""
        def fire(value: Any) -> None:
            self._submit_step({"topic": topic}, snapshot=(topic.name, value))

        return fire

    def _submit_step(self, kwargs: dict[str, Any], snapshot: tuple[str, Any] | None = None) -> None:
        """Queue one ``_execution_step(**kwargs)`` on the worker (dropped and counted unless active)."""
        self.runtime.submit_step(kwargs, snapshot)

    def _set_health(self, status: HealthStatus, message: str) -> None:
        """Set the health from within the component (a change is reported at once)."""
        self.runtime.health.set(status, message)

    def _execution_step(self, **kwargs: Any) -> None:
        """One unit of work; called on the component's worker each time the trigger fires."""
        raise NotImplementedError(f"{type(self).__name__} must implement _execution_step()")

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.component_name!r} {self.runtime.state.value}>"
