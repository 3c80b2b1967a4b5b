"""``Launcher``: runs a recipe's components on a transport.

Blocking, for a robot::

    launcher = Launcher(transport="zenoh")      # None reads AGENTS_TRANSPORT (default "memory")
    launcher.add_pkg(components=[llm, vision], events_actions={low_battery: Action(llm.deactivate)})
    launcher.bringup()                          # until SIGINT / SIGTERM, then a clean shutdown

Non-blocking, for tests and embedding::

    with Launcher(transport="memory") as launcher:   # start() on enter, stop() on exit
        pub = launcher.transport.create_publisher(Topic("question", "String"))
        pub.publish("hello")

The launcher watches every event of a component trigger or ``events_actions`` with one subscription
per event topic, and runs each action on the worker of the component that owns the method (or on
the launcher's own action worker for other callables).

With ``add_pkg(..., multiprocessing=True)`` each component runs in a process of its own (see
:mod:`agents_core.launch`), respawned when it crashes (``on_process_fail``). The launcher keeps its
own transport to watch events; an action on a component in another process runs through that
component's services (``<name>/execute_method`` for ``@component_action`` methods, the lifecycle for
``activate`` / ``deactivate`` / ...).

A component triggered by an Event runs in its process too: the launcher evaluates the event (it
watches every event's topics) and sends each firing down that process's command pipe, where a
stand-in event of the same name fires the component's step. ``Launcher()`` with
``multiprocessing=True`` and no transport named anywhere (argument, ``AGENTS_TRANSPORT``, config
file) runs on Zenoh when it is installed, saying so in the log, and otherwise in one process
with a WARNING, as upstream recipes expect; a memory transport named explicitly is refused.

``Launcher(config_file="robot.yaml")`` reads the transport settings (a ``transport`` section:
``name`` plus the transport's options) and one section per component name (its config fields)
from one YAML or TOML file.
"""

from __future__ import annotations

import difflib
import functools
import logging
import os
import sys
import threading
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from ..actions import Action
from ..components.component_base import Component
from ..console import say
from ..errors import ComponentError, ConfigError, WiringError
from ..events import Event, EventListener
from ..install_hint import install_hint
from ..runtime.worker import StepWorker
from ..status import LifecycleState
from ..transport.contract import Subscription, Transport
from ..transport.registry import TRANSPORT_ENV_VAR, resolve_transport
from .live_status import LiveStatus, Row, child_rows, component_rows
from .preflight import (
    LIFECYCLE_METHODS,
    check_remote_action,
    check_transferable,
    cross_process_transports,
    read_launch_file,
    refuse_inside_component_process,
)
from .process_start import process_start as choose_process_start
from .report import LaunchReport, component_row
from .short_errors import short_errors
from .stop_signals import stop_signals
from .upstream_args import apply_add_pkg_extras

if TYPE_CHECKING:
    from .fork_server import ForkServer
    from .supervisor import Supervisor

__all__ = ["Launcher"]

logger = logging.getLogger(__name__)


def _feed_event(event: Event, topic_name: str, value: Any) -> None:
    event.process(topic_name, value)


class Launcher:
    """Brings up components on a transport and takes them down cleanly.

    :param transport: a transport name (``"memory"``, ``"zenoh"``, ``"ros2"``), a transport
        object, or None to read ``AGENTS_TRANSPORT``.
    :param transport_options: keyword options for the transport's constructor (with a name).
    :param config_file: a YAML or TOML file with a ``transport`` section (``name`` and the
        transport's options; what is passed here explicitly wins) and a section per component
        name with config fields, applied when the launcher starts.
    :param quiet: True: print no status lines. By default :meth:`start` prints a few lines on
        stderr (transport, components, UI address, how to stop; :mod:`agents_core.launch.report`)
        unless ``AGENTS_QUIET=1`` or the ``agents_core`` logger has a level above INFO.
    :param process_start: with ``multiprocessing=True``, ``"fork"`` (component processes forked by
        a pre-imported server, :mod:`agents_core.launch.fork_server`; the default on Linux) or
        ``"spawn"`` (a fresh interpreter each); None reads ``AGENTS_PROCESS_START``.
    """

    def __init__(self, transport: str | Transport | None = None, *,
                 transport_options: Mapping[str, Any] | None = None,
                 config_file: str | os.PathLike[str] | None = None, quiet: bool | None = None,
                 process_start: str | None = None) -> None:
        self._quiet = quiet
        try:
            self._process_start = choose_process_start(process_start)
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        self._fork_server: ForkServer | None = None
        self._component_sections: dict[str, dict[str, Any]] = {}
        self._config_file = str(config_file) if config_file is not None else None
        file_transport: dict[str, Any] = {}
        if self._config_file is not None:
            file_transport, self._component_sections = read_launch_file(self._config_file)
        file_name = file_transport.pop("name", None)
        if transport is None and file_name is not None and not os.environ.get(TRANSPORT_ENV_VAR, "").strip():
            transport = file_name
        self._transport_spec = transport
        self._transport_options = {**(file_transport if isinstance(transport, str | None) else {}),
                                   **dict(transport_options or {})}
        self._transport: Transport | None = None
        self._owns_transport = False
        self.components: list[Component] = []
        self.events_actions: dict[Event, list[Action]] = {}
        self._event_subscriptions: list[Subscription] = []
        self._event_runners: list[tuple[Event, EventListener]] = []
        self._action_worker: StepWorker | None = None
        self._started = False
        self._stop_requested = threading.Event()
        self._hurry = threading.Event()
        self._process_fail_retries: int | None = None
        self._process_giveup: Action | None = None
        self._multiprocessing = False
        self._fail_action: tuple[str, int | None] | None = None
        self._fallback_rate: float | None = None
        self._supervisor: Supervisor | None = None
        self._stopped_supervisor: Supervisor | None = None
        self._ui_options: dict[str, Any] | None = None
        self._ui: Any = None
        self._foxglove_options: dict[str, Any] | None = None
        self._foxglove: Any = None
        self._recording: Any = None
        self._live_status: LiveStatus | None = None

    # -- recipe -------------------------------------------------------------------------------

    def add_pkg(self, components: Sequence[Component],
                events_actions: Mapping[Event, Action | Sequence[Action]] | None = None,
                multiprocessing: bool = False, package_name: str | None = None, **upstream: Any) -> None:
        """Add components (and event -> action wiring) to launch.

        ``multiprocessing=True`` (one process per component) needs a transport whose capabilities
        say ``cross_process``; the memory transport, which lives in one process, is refused at start.
        ``package_name`` is accepted for upstream recipes (ROS packages) and not needed here; so is
        ``ros_log_level`` (:mod:`.upstream_args`); any other argument is a ConfigError naming it.
        """
        if self._started:
            raise ConfigError("add_pkg() must be called before the launcher starts")
        self._multiprocessing = self._multiprocessing or bool(multiprocessing)
        for c in components:
            if not isinstance(c, Component):
                raise WiringError(f"add_pkg() takes components, got {type(c).__name__}")
            if any(c.component_name == other.component_name for other in self.components):
                raise WiringError(f"two components are named {c.component_name!r}; names must be unique")
            self.components.append(c)
        apply_add_pkg_extras(components, upstream)  # upstream's ros_log_level, ... (upstream_args)
        if self._multiprocessing:
            check_transferable(self.components)
            self._prepare_fork_server()
        for event, actions in (events_actions or {}).items():
            if not isinstance(event, Event):
                raise WiringError(f"events_actions keys must be Event objects, got {type(event).__name__}")
            action_list = [actions] if isinstance(actions, Action) else list(actions)
            for a in action_list:
                if not isinstance(a, Action):
                    raise WiringError(f"event {event.name!r}: {a!r} is not an Action")
            self.events_actions.setdefault(event, []).extend(action_list)

    def enable_ui(self, inputs: Sequence[Any] | None = None, outputs: Sequence[Any] | None = None,
                  port: int = 5001, **settings: Any) -> None:
        """Serve the web UI (``agents_core.ui``, the ``ui`` extra) while the recipe runs.

        ``inputs`` / ``outputs``: the topics the page may publish on and shows (None: the recipe's
        unfed inputs / every output). Other keywords are :class:`agents_core.ui.UISettings` fields
        (``host``, ``token``, ``max_upload_bytes``, ...); it binds 127.0.0.1 unless told otherwise.
        """
        from ..ui.settings import UISettings  # noqa: PLC0415  (the UI is optional)

        if self._started:
            raise ConfigError("enable_ui() must be called before the launcher starts")
        self._ui_options = {"inputs": inputs, "outputs": outputs, "settings": UISettings(port=port, **settings)}

    @property
    def ui(self) -> Any:
        """The running :class:`agents_core.ui.UIServer` (its ``url``, ``port``), or None."""
        return self._ui

    def enable_foxglove(self, topics: Sequence[Any] | None = None, port: int = 8765, **settings: Any) -> None:
        """Serve the recipe's topics to Foxglove (``agents_core.foxglove``, the ``foxglove`` extra) while it runs.

        ``topics``: those to serve (None: every input and output); the status topics always. Other
        keywords are :class:`agents_core.foxglove.FoxgloveSettings` fields; it binds 127.0.0.1.
        """
        from ..foxglove.settings import FoxgloveSettings  # noqa: PLC0415  (Foxglove is optional)

        if self._started:
            raise ConfigError("enable_foxglove() must be called before the launcher starts")
        self._foxglove_options = {"topics": topics, "settings": FoxgloveSettings(port=port, **settings)}

    @property
    def foxglove(self) -> Any:
        """The running :class:`agents_core.foxglove.FoxgloveBridge` (its ``url``, ``port``), or None."""
        return self._foxglove

    def record(self, path: str | os.PathLike[str], **options: Any) -> Any:
        """Record the recipe's topics into MCAP while it runs: :class:`agents_core.recording.launch.RecipeRecording`."""
        from ..recording.launch import RecipeRecording  # noqa: PLC0415  (recording is optional)
        self._recording = RecipeRecording(path, **options)
        return self._recording

    def on_process_fail(self, max_retries: int = 3, on_giveup: Action | None = None) -> None:
        """Respawn a crashed component process up to ``max_retries`` times (multiprocessing runs).

        Respawns back off (none for the first, then 100 ms doubled per restart, at most 2 s).
        After the last one the launcher logs the give-up and runs ``on_giveup`` (see :meth:`on_giveup`).
        """
        if isinstance(max_retries, bool) or not isinstance(max_retries, int) or max_retries < 0:
            raise ConfigError(f"on_process_fail: max_retries must be an int >= 0, got {max_retries!r}")
        self._process_fail_retries = max_retries
        if on_giveup is not None:
            self.on_giveup(on_giveup)

    def on_fail(self, action_name: str, max_retries: int | None = None) -> None:
        """Give every component the fallback ``component.<action_name>()`` for any failure (upstream's form).

        ``launcher.on_fail(action_name="restart")`` is ``c.on_fail(Action(c.restart), max_retries)`` for each
        component, applied at start (to the components added by then). A component without that
        method is refused at start, naming it.
        """
        if not isinstance(action_name, str) or not action_name.isidentifier():
            raise ConfigError(f"on_fail: action_name must be a method name such as 'restart', got {action_name!r}")
        if max_retries is not None and (isinstance(max_retries, bool) or not isinstance(max_retries, int)
                                        or max_retries < 0):
            raise ConfigError(f"on_fail: max_retries must be an int >= 0 or None, got {max_retries!r}")
        self._fail_action = (action_name, max_retries)

    @property
    def fallback_rate(self) -> float | None:
        """Upstream's polling rate of fallbacks (Hz). Here a fallback runs as soon as a failure is seen,
        with no polling: the value is checked and kept, and the launcher says once at start that it
        does not delay fallbacks."""
        return self._fallback_rate

    @fallback_rate.setter
    def fallback_rate(self, rate: float | None) -> None:
        if rate is not None and (isinstance(rate, bool) or not isinstance(rate, int | float) or not rate > 0):
            raise ConfigError(f"fallback_rate must be a rate in Hz > 0, got {rate!r}")
        self._fallback_rate = None if rate is None else float(rate)

    def on_giveup(self, action: Action) -> None:
        """Run ``action`` once a component process has crashed more often than ``on_process_fail`` allows."""
        if not isinstance(action, Action):
            raise WiringError(f"on_giveup takes an Action, got {type(action).__name__}")
        self._process_giveup = action

    @property
    def transport(self) -> Transport:
        """The running transport (available after :meth:`start`)."""
        if self._transport is None:
            raise ConfigError("the launcher has not started; call start() (or use it as a context manager)")
        return self._transport

    # -- running ------------------------------------------------------------------------------

    def start(self) -> Launcher:
        """Bind, configure and activate every component; returns self. Stops everything on failure."""
        if self._started:
            raise ConfigError("the launcher is already started")
        if not self.components:
            raise ConfigError("nothing to launch: call add_pkg(components=[...]) first")
        refuse_inside_component_process()
        self._apply_component_sections()
        self._apply_fail_action()
        self._choose_default_transport()  # then the fork server, which imports the adapter meanwhile
        self._transport = resolve_transport(self._transport_spec, **self._transport_options)
        self._owns_transport = isinstance(self._transport_spec, str) or self._transport_spec is None
        if self._multiprocessing and not self._transport.capabilities.cross_process:
            transport, self._transport = self._transport, None
            if self._owns_transport:
                transport.close()
            raise ConfigError(f"multiprocessing=True needs a transport whose capabilities say cross_process "
                              f"({', '.join(cross_process_transports()) or 'none installed'}); "
                              f"{transport.name!r} lives in one process")
        self._started = True
        report = LaunchReport(self._quiet)
        report.transport(self._transport)
        failing: tuple[str | None, str] = (None, "start")
        try:
            self._action_worker = StepWorker("launcher-actions", 1, "drop_newest")
            for event, actions in self.events_actions.items():
                runner = self._make_event_runner(actions)
                event.add_listener(runner)
                self._event_runners.append((event, runner))
            if self._multiprocessing:
                self._start_processes()
                self._watch_events()
                for row in self._supervisor.describe() if self._supervisor is not None else []:
                    report.component(str(row["name"]), str(row["state"]), "-", f"own process, pid {row['pid']}")
            else:
                for c in self.components:
                    c.runtime.bind(self._transport)
                self._watch_events()
                for c in self.components:
                    failing = (c.component_name, "configure")
                    c.configure()
                for c in self.components:
                    failing = (c.component_name, "activate")
                    c.activate()
                    report.component(*component_row(c))
            failing = (None, "start the web UI")
            self._start_ui(report)
            failing = (None, "start the Foxglove server")
            self._start_foxglove(report)
        except BaseException as exc:
            report.failed(*failing, exc)
            self.stop()
            raise
        report.running(len(self.components))
        self._live_status = LiveStatus(report, self._status_rows)
        self._live_status.start()
        logger.info("launched %d component(s) on %s", len(self.components), self._transport.name)
        return self

    def _start_ui(self, report: LaunchReport) -> None:
        if self._ui_options is not None:
            from ..ui.launch import start_ui  # noqa: PLC0415  (the UI is optional)

            self._ui = start_ui(self.components, self.transport, **self._ui_options)
            report.ui(str(self._ui.url))

    def _start_foxglove(self, report: LaunchReport) -> None:
        if self._foxglove_options is not None:
            from ..foxglove.launch import start_foxglove  # noqa: PLC0415  (Foxglove is optional)

            self._foxglove = start_foxglove(self.components, self.transport, **self._foxglove_options)
            report.foxglove(self._foxglove.url)

    def _apply_fail_action(self) -> None:
        if self._fallback_rate is not None:
            logger.warning("fallback_rate=%g Hz is not a polling rate here: each fallback runs as soon as its "
                           "component reports the failure", self._fallback_rate)
        if self._fail_action is None:
            return
        action_name, max_retries = self._fail_action
        for c in self.components:
            method = getattr(c, action_name, None)
            if not callable(method):
                raise ConfigError(f"on_fail(action_name={action_name!r}): component {c.component_name!r} "
                                  f"({type(c).__name__}) has no method {action_name!r}")
            c.on_fail(Action(method), max_retries)

    def _choose_default_transport(self) -> None:
        """``multiprocessing=True`` with no transport named anywhere: Zenoh if installed, else one process.

        Then (before the transport opens) the fork server is prepared for the transport's adapter.
        """
        self._default_transport()
        self._prepare_fork_server()

    def _default_transport(self) -> None:
        if not self._multiprocessing or self._transport_spec is not None \
                or os.environ.get(TRANSPORT_ENV_VAR, "").strip():
            return
        if "zenoh" in cross_process_transports():
            logger.info("multiprocessing=True and no transport named: running the component processes on "
                        "'zenoh' (name one with Launcher(transport=...) or %s)", TRANSPORT_ENV_VAR)
            self._transport_spec = "zenoh"
        else:
            logger.warning("multiprocessing=True needs a cross-process transport and none is installed "
                           "(%s): running every component in this one process", install_hint("zenoh"))
            self._multiprocessing = False

    def _apply_component_sections(self) -> None:
        names = [c.component_name for c in self.components]
        for name in self._component_sections:
            if name not in names:
                close = difflib.get_close_matches(name, names, n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise ConfigError(f"config file {self._config_file}: section {name!r} names no component "
                                  f"of this launcher{hint} (components: {names})")
        for c in self.components:
            section = self._component_sections.get(c.component_name)
            if section:
                try:
                    c.config.update(**section)
                except ConfigError as exc:
                    raise ConfigError(f"config file {self._config_file}, section {c.component_name!r}: {exc}") \
                        from exc

    def _prepare_fork_server(self) -> None:
        """Start (or reuse) the fork server and have it import what the component processes need."""
        recipe_import = sys.modules.get("agents_core.launch.recipe_import")
        if not self._multiprocessing or self._process_start != "fork" or (
                recipe_import is not None and recipe_import.importing_recipe()):
            return  # a component process importing its recipe never starts a server
        from .fork_server import adapter_module, prepare  # noqa: PLC0415 - multiprocessing only
        self._fork_server = prepare({type(c).__module__ for c in self.components}, sys.path,
                                    adapter_module(self._transport_spec))

    def _start_processes(self) -> None:
        from .spec import ComponentSpec, check_rebuild  # noqa: PLC0415
        from .supervisor import Supervisor  # noqa: PLC0415

        transport = self.transport
        # A transport may say how another process reaches it (Zenoh: connect to this session's
        # listening endpoints); by default ({}) a child opens it with the same options.
        options = transport.peer_process_options() or dict(self._transport_options)
        specs = []
        for c in self.components:
            spec = ComponentSpec.from_component(c, transport.name, options, os.getpid())
            check_rebuild(c, spec)
            specs.append(spec)
        for event, actions in self.events_actions.items():
            for action in actions:
                check_remote_action(event, action)
        retries = self._process_fail_retries if self._process_fail_retries is not None else 0
        self._supervisor = Supervisor(specs, max_retries=retries, on_giveup=self._gave_up_on,
                                      fork_server=self._fork_server)
        for c in self.components:
            if isinstance(c.trigger, Event):
                forward = functools.partial(_forward_trigger, self._supervisor, c.component_name)
                c.trigger.add_listener(forward)
                self._event_runners.append((c.trigger, forward))
        self._supervisor.start()

    def _gave_up_on(self, component_name: str) -> None:
        if self._process_fail_retries is None:
            logger.error("component %r: its process crashed; not restarting it (launcher.on_process_fail("
                         "max_retries) respawns crashed components)", component_name)
        else:
            logger.error("component %r: its process crashed more often than on_process_fail(max_retries=%d) "
                         "allows; not restarting it", component_name, self._process_fail_retries)
        action = self._process_giveup
        if action is not None and self._action_worker is not None:
            self._action_worker.submit_control(functools.partial(self._run_giveup, action))

    def _run_giveup(self, action: Action) -> None:
        try:
            self._call_action(action, {})
        except Exception:
            logger.exception("the on_giveup action %s failed", action.name)

    @property
    def supervisor(self) -> Supervisor | None:
        """The component processes (pids, states, restarts) of a multiprocessing run, else None."""
        return self._supervisor

    def _call_action(self, action: Action, values: Mapping[str, Any]) -> Any:
        """Run ``action`` here, or through the services of its component when that runs in a process."""
        owner = action.owner
        if self._supervisor is None or not isinstance(owner, Component):
            return action(values)
        args, kwargs = action.resolve(values)
        name = action.name
        if name in LIFECYCLE_METHODS:
            if not self.transport.request_transition(owner.component_name, name, timeout=10.0):
                raise ComponentError(f"component {owner.component_name!r} refused the transition {name!r}")
            return None
        reply = self.transport.request(f"{owner.component_name}/execute_method",
                                       {"method": name, "args": list(args), "kwargs": kwargs}, timeout=30.0)
        return reply.get("result")

    def _watch_events(self) -> None:
        """The launcher's own subscribers on the transport: its events' topics, and the recording if any."""
        if self._recording is not None:
            self._recording.start(self.components, self.transport)
        events = set(self.events_actions)
        events.update(c.trigger for c in self.components if isinstance(c.trigger, Event))
        for event in events:
            for topic in event.topics.values():
                self._event_subscriptions.append(self.transport.create_subscription(
                    topic, functools.partial(_feed_event, event, topic.name)))

    def _make_event_runner(self, actions: list[Action]) -> EventListener:
        def run(event: Event, values: Mapping[str, Any]) -> None:
            for action in actions:
                owner = action.owner
                job = functools.partial(self._run_action, event, action, values)
                if isinstance(owner, Component) and owner.runtime.is_bound and self._supervisor is None:
                    owner.runtime.submit_action(job)
                elif self._action_worker is not None:
                    self._action_worker.submit_control(job)

        return run

    def _run_action(self, event: Event, action: Action, values: Mapping[str, Any]) -> None:
        try:
            self._call_action(action, values)
        except Exception:
            logger.exception("action %s for event %r failed", action.name, event.name)

    def stop(self) -> None:
        """Deactivate and shut down every component, then close the transport if the launcher made it.

        The transport is closed whatever happens before (a component that fails to stop, an
        interrupt): its threads and shared-memory segments must not outlive the recipe.
        """
        try:
            live, self._live_status = self._live_status, None
            if live is not None:
                live.stop()
            ui, self._ui = self._ui, None
            if ui is not None:
                ui.stop()
            foxglove, self._foxglove = self._foxglove, None
            if foxglove is not None:
                foxglove.stop()
            for sub in self._event_subscriptions:
                sub.close()
            self._event_subscriptions.clear()
            for event, runner in self._event_runners:
                event.remove_listener(runner)
            self._event_runners.clear()
            if self._supervisor is not None:
                supervisor, self._supervisor = self._supervisor, None
                supervisor.stop()
                self._stopped_supervisor = supervisor
            for c in reversed(self.components):
                if not c.runtime.is_bound:
                    continue
                try:
                    c.shutdown()
                except Exception as exc:
                    logger.warning("component %r did not shut down cleanly: %s", c.component_name, exc)
            if self._action_worker is not None:
                self._action_worker.stop(timeout=2.0, abort=self._hurry)
                self._action_worker = None
        finally:
            if self._recording is not None:
                self._recording.stop()
            if self._transport is not None and self._owns_transport:
                self._transport.close()
            if self._stopped_supervisor is not None:
                # This process may have mapped a crashed child's segment until its transport closed.
                self._stopped_supervisor.remove_orphan_shm()
                self._stopped_supervisor = None
            self._started = False

    def _status_rows(self) -> list[Row]:
        supervisor = self._supervisor
        if supervisor is not None:
            return child_rows(supervisor.describe, supervisor.max_retries)
        return component_rows(self.components)

    def hurry(self) -> None:
        """Make a running or coming :meth:`stop` stop waiting for components' running steps."""
        self._hurry.set()
        for c in self.components:
            c.runtime.hurry()

    def all_active(self) -> bool:
        """True when every component is in the active state (in its own process, if it has one)."""
        if self._supervisor is not None:
            return self._supervisor.all_active()
        return all(c.lifecycle_state == LifecycleState.ACTIVE for c in self.components)

    def bringup(self) -> None:
        """Start, run until SIGINT / SIGTERM (or :meth:`request_stop`), then stop cleanly.

        The first signal starts a clean shutdown (running steps get ``step_finish_timeout`` to
        finish); a second one makes it hurry (nothing more is waited for, the transport is still
        closed); a third exits the process at once with status 128 + the signal number.
        """
        with short_errors(), stop_signals(self._stop_requested.set, self.hurry, quiet=self._quiet):
            try:
                self.start()
                while not self._stop_requested.wait(0.5):
                    pass
            finally:
                self.stop()
                say("agents: stopped", quiet=self._quiet)

    def request_stop(self) -> None:
        """Make :meth:`bringup` return (thread-safe)."""
        self._stop_requested.set()

    def __enter__(self) -> Launcher:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _forward_trigger(supervisor: Supervisor, component_name: str, event: Event, values: Mapping[str, Any]) -> None:
    """The trigger event of a component in its own process fired here: fire its stand-in there."""
    if not supervisor.child(component_name).send("fire-trigger"):
        logger.debug("component %r is not running: trigger event %r dropped", component_name, event.name)
