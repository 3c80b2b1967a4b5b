"""``Launcher``: upstream's API over a :class:`~agents_core.launch.recipe.Recipe` and a run.

Blocking, for a robot::

    launcher = Launcher(transport="zenoh")      # None reads AGENTS_TRANSPORT (default "memory")
    launcher.add_pkg(components=[llm, vision], events_actions={low_battery: Action(llm.deactivate)})
    launcher.bringup()                          # until SIGINT / SIGTERM, then a clean shutdown

Non-blocking, for tests and embedding: ``with Launcher(transport="memory") as launcher:`` (start()
on enter, stop() on exit; ``launcher.transport`` reaches the components).

What ``add_pkg``, ``on_fail``, ``enable_ui``, ... are given is held as data in :attr:`Launcher.recipe`
(``agentsctl recipe show`` prints it); :meth:`Launcher.start` opens the transport and starts one run
(:mod:`agents_core.launch.runs`: this process, or a process per component with ``add_pkg(...,
multiprocessing=True)``), the events (:mod:`agents_core.launch.event_wiring`) and the attachments.
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from .. import telemetry as _telemetry
from ..actions import Action
from ..components.component_base import Component
from ..errors import ConfigError
from ..events import Event
from ..status import LifecycleState
from ..support.console import say
from ..support.install_hint import install_hint
from ..transport.contract import Transport
from ..transport.registry import DEFAULT_CROSS_PROCESS, TRANSPORT_ENV_VAR, cross_process_transports
from ..transport.registry import describe_transport_kind as _describe
from .attachments import RunningAttachments, foxglove_options, record_options, ui_options
from .event_wiring import EventWiring
from .live_status import LiveStatus, Row, component_rows
from .preflight import (
    apply_fail_action,
    apply_launch_file,
    check_transferable,
    launch_settings,
    refuse_inside_component_process,
)
from .recipe import Recipe, stop_if_capturing
from .report import LaunchReport
from .runs import ProcessRun, Run, ThreadRun, prepare_fork_server
from .short_errors import short_errors
from .stop_signals import stop_signals
from .upstream_args import apply_add_pkg_extras

if TYPE_CHECKING:
    from .fork_server import ForkServer
    from .supervisor import Supervisor

__all__ = ["Launcher"]

logger = logging.getLogger(__name__)


class Launcher:
    """Brings up components on a transport and takes them down cleanly.

    :param transport: a transport name (``"memory"``, ``"zenoh"``, ``"ros2"`` or an installed
        one's), a transport object, or None to read ``AGENTS_TRANSPORT``.
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
    :param telemetry: OpenTelemetry traces and metrics (:mod:`agents_core.telemetry`); None: ``OTEL_*`` variables.
    :param namespace: run under this namespace (``"robot1"``; None reads ``AGENTS_NAMESPACE``) as ROS 2 does:
        components and relative topics are ``robot1/...`` on the wire (:mod:`agents_core.transport.namespace`).
    """

    def __init__(self, transport: str | Transport | None = None, *,
                 transport_options: Mapping[str, Any] | None = None,
                 config_file: str | os.PathLike[str] | None = None, quiet: bool | None = None,
                 process_start: str | None = None, telemetry: Any = None, namespace: str | None = None) -> None:
        self._quiet, self._telemetry = quiet, _telemetry.telemetry_settings(telemetry)  # on at start
        settings, self._component_sections = launch_settings(transport, transport_options, config_file, process_start)
        settings.set_namespace(namespace)
        #: What this launcher runs, as data (:mod:`agents_core.launch.recipe`).
        self.recipe = Recipe(settings=settings)
        self._fork_server: ForkServer | None = None
        self._transport: Transport | None = None
        self._owns_transport = False
        self._run: Run | None = None
        self._wiring: EventWiring | None = None
        self._attached = RunningAttachments({})
        self._started = False
        self._stop_requested = threading.Event()
        self._hurry = threading.Event()
        self._live_status: LiveStatus | None = None

    # -- recipe -------------------------------------------------------------------------------

    @property
    def components(self) -> list[Component]:
        """The recipe's components, in the order they were added."""
        return self.recipe.components

    @property
    def events_actions(self) -> dict[Event, list[Action]]:
        """The recipe's event -> actions wiring."""
        return self.recipe.events_actions

    _transport_spec = property(lambda self: self.recipe.settings.transport)

    def add_pkg(self, components: Sequence[Component],
                events_actions: Mapping[Event, Action | Sequence[Action]] | None = None,
                multiprocessing: bool = False, package_name: str | None = None, **upstream: Any) -> None:
        """Add components (and event -> action wiring) to launch.

        ``multiprocessing=True`` (one process per component) needs a transport whose capabilities
        say ``cross_process``; the memory transport, which lives in one process, is refused at start.
        ``package_name`` is accepted for upstream recipes (ROS packages) and not needed here; so is
        ``ros_log_level`` (:mod:`.upstream_args`); any other argument is a ConfigError naming it.
        """
        self._refuse_started("add_pkg()")
        self.recipe.add(components, events_actions, multiprocessing)
        apply_add_pkg_extras(components, upstream)  # upstream's ros_log_level, ... (upstream_args)
        if self.recipe.settings.multiprocessing:
            check_transferable(self.components)
            self._fork_server = prepare_fork_server(self.recipe) or self._fork_server

    def enable_ui(self, inputs: Sequence[Any] | None = None, outputs: Sequence[Any] | None = None,
                  port: int = 5001, **settings: Any) -> None:
        """Serve the web UI (``agents_core.ui``, the ``ui`` extra) while the recipe runs.

        ``inputs`` / ``outputs``: the topics the page may publish on and shows (None: the recipe's
        unfed inputs / every output). Other keywords are :class:`agents_core.ui.UISettings` fields
        (``host``, ``token``, ``max_upload_bytes``, ...); it binds 127.0.0.1 unless told otherwise.
        """
        self._refuse_started("enable_ui()")
        self.recipe.attachments["ui"] = ui_options(inputs, outputs, port, **settings)

    @property
    def ui(self) -> Any:
        """The running :class:`agents_core.ui.UIServer` (its ``url``, ``port``), or None."""
        return self._attached.get("ui")

    def enable_foxglove(self, topics: Sequence[Any] | None = None, port: int = 8765, **settings: Any) -> None:
        """Serve the recipe's topics to Foxglove (``agents_core.foxglove``, the ``foxglove`` extra) while it runs.

        ``topics``: those to serve (None: every input and output); the status topics always. Other
        keywords are :class:`agents_core.foxglove.FoxgloveSettings` fields; it binds 127.0.0.1.
        """
        self._refuse_started("enable_foxglove()")
        self.recipe.attachments["foxglove"] = foxglove_options(topics, port, **settings)

    @property
    def foxglove(self) -> Any:
        """The running :class:`agents_core.foxglove.FoxgloveBridge` (its ``url``, ``port``), or None."""
        return self._attached.get("foxglove")

    def enable_mcp(self, host: str = "127.0.0.1", port: int = 5002, **options: Any) -> None:
        """Serve the recipe over MCP at ``http://host:port/mcp`` (:func:`agents_core.mcp.attach.mcp_options`)."""
        from ..mcp.attach import mcp_options  # noqa: PLC0415  (the mcp extra)
        self._refuse_started("enable_mcp()")
        self.recipe.attachments["mcp"] = mcp_options(host, port, **options)

    @property
    def mcp(self) -> Any:
        """The running :class:`agents_core.mcp.McpHttpServer` (its ``url``), or None."""
        return self._attached.get("mcp")

    def record(self, path: str | os.PathLike[str], **options: Any) -> Any:
        """Record the recipe's topics into MCAP while it runs: :class:`agents_core.recording.launch.RecipeRecording`."""
        self.recipe.attachments["record"] = record_options(path, **options)
        return self.recipe.attachments["record"]["recording"]

    def on_process_fail(self, max_retries: int = 3, on_giveup: Action | None = None) -> None:
        """Respawn a crashed component process up to ``max_retries`` times (multiprocessing runs), backing off
        (none for the first, then 100 ms doubled, at most 2 s); then log the give-up and run ``on_giveup``."""
        self.recipe.settings.set_process_fail(max_retries, on_giveup)

    def on_fail(self, action_name: str, max_retries: int | None = None) -> None:
        """Give every component the fallback ``component.<action_name>()`` for any failure (upstream's form):
        ``c.on_fail(Action(c.restart), max_retries)`` for each component at start; one without it is refused."""
        self.recipe.settings.set_fail_action(action_name, max_retries)

    @property
    def fallback_rate(self) -> float | None:
        """Upstream's polling rate of fallbacks (Hz): checked and kept; a fallback here runs at once, unpolled."""
        return self.recipe.settings.fallback_rate

    @fallback_rate.setter
    def fallback_rate(self, rate: float | None) -> None:
        self.recipe.settings.set_fallback_rate(rate)

    def on_giveup(self, action: Action) -> None:
        """Run ``action`` once a component process has crashed more often than ``on_process_fail`` allows."""
        self.recipe.settings.set_giveup(action)

    @property
    def transport(self) -> Transport:
        """The running transport (available after :meth:`start`)."""
        if self._transport is None:
            raise ConfigError("the launcher has not started; call start() (or use it as a context manager)")
        return self._transport

    @property
    def supervisor(self) -> Supervisor | None:
        """The component processes (pids, states, restarts) of a multiprocessing run, else None."""
        return self._run.supervisor if isinstance(self._run, ProcessRun) else None

    def _refuse_started(self, what: str) -> None:
        if self._started:
            raise ConfigError(f"{what} must be called before the launcher starts")

    # -- running ------------------------------------------------------------------------------

    def start(self) -> Launcher:
        """Bind, configure and activate every component; returns self. Stops everything on failure."""
        if self._started:
            raise ConfigError("the launcher is already started")
        stop_if_capturing(self.recipe)  # `agentsctl recipe show`: the recipe is complete here
        if not self.components:
            raise ConfigError("nothing to launch: call add_pkg(components=[...]) first")
        refuse_inside_component_process()
        settings = self.recipe.settings
        apply_launch_file(self.components, self._component_sections, settings.config_file)
        apply_fail_action(self.components, settings.fail_action, settings.fallback_rate)
        self._choose_default_transport()  # then the fork server, which imports the adapter meanwhile
        self._transport, self._owns_transport = transport, _ = settings.open_transport()  # namespaced, if any
        if settings.multiprocessing and not transport.capabilities.cross_process:
            self._transport = None
            if self._owns_transport:
                transport.close()
            raise ConfigError(f"multiprocessing=True needs a transport whose capabilities say cross_process "
                              f"({', '.join(cross_process_transports()) or 'none installed'}); "
                              f"{transport.name!r} lives in one process")
        self._started = True
        _telemetry.configure(self._telemetry)  # before the run: its component specs carry the settings
        report = LaunchReport(self._quiet)
        report.transport(transport)
        failing: list[tuple[str | None, str]] = [(None, "start")]
        try:
            self._wiring = wiring = EventWiring(self.recipe, self._hurry)
            if settings.multiprocessing:
                self._run = ProcessRun(self.recipe, transport, wiring, report, fork_server=self._fork_server)
            else:
                self._run = ThreadRun(self.recipe, transport, wiring, report)
            wiring.arm(self._run)
            self._attached = RunningAttachments(self.recipe.attachments)
            self._attached.start("before", self.components, transport, report, failing)
            self._run.start(failing)
            self._attached.start("after", self.components, transport, report, failing)
        except BaseException as exc:
            report.failed(*failing[0], exc)
            self.stop()
            raise
        report.running(len(self.components))
        self._live_status = LiveStatus(report, self._status_rows)
        self._live_status.start()
        logger.info("launched %d component(s) on %s", len(self.components), transport.name)
        return self

    def _choose_default_transport(self) -> None:
        """``multiprocessing=True`` with no transport named anywhere (argument, ``AGENTS_TRANSPORT``, config file):
        the first installed cross-process one (Zenoh), saying so, else one process with a WARNING. Then (before
        the transport opens) the fork server is prepared for the transport's adapter."""
        settings = self.recipe.settings
        named = settings.transport is not None or os.environ.get(TRANSPORT_ENV_VAR, "").strip()
        if settings.multiprocessing and not named:
            offered = cross_process_transports()
            if offered:
                logger.info("multiprocessing=True and no transport named: running the component processes on "
                            "%r (name one with Launcher(transport=...) or %s)", offered[0], TRANSPORT_ENV_VAR)
                settings.transport = offered[0]
            else:
                hint = install_hint(str(_describe(DEFAULT_CROSS_PROCESS).extra))
                logger.warning("multiprocessing=True needs a cross-process transport and none is installed (%s): "
                               "running every component in this one process", hint)
                settings.multiprocessing = False
        self._fork_server = prepare_fork_server(self.recipe) or self._fork_server

    def stop(self) -> None:
        """Deactivate and shut down every component, then close the transport if the launcher made it.

        The transport is closed whatever happens before (a component that fails to stop, an interrupt):
        its threads and shared-memory segments must not outlive the recipe.
        """
        run, wiring = self._run, self._wiring
        try:
            live, self._live_status = self._live_status, None
            if live is not None:
                live.stop()
            self._attached.stop("after")
            if wiring is not None:
                wiring.close_subscriptions()
            if run is not None:
                run.stop()
            if wiring is not None:
                wiring.disarm()
        finally:
            self._attached.stop("before")
            if self._transport is not None and self._owns_transport:
                self._transport.close()
            if run is not None:
                run.after_transport_closed()
            self._started = False

    def _status_rows(self) -> list[Row]:
        return self._run.status_rows() if self._run is not None else component_rows(self.components)

    def hurry(self) -> None:
        """Make a running or coming :meth:`stop` stop waiting for components' running steps."""
        self._hurry.set()
        for c in self.components:
            c.runtime.hurry()

    def all_active(self) -> bool:
        """True when every component is in the active state (in its own process, if it has one)."""
        if self._run is not None:
            return self._run.all_active()
        return all(c.lifecycle_state == LifecycleState.ACTIVE for c in self.components)

    def bringup(self) -> None:
        """Start, run until SIGINT / SIGTERM (or :meth:`request_stop`), then stop cleanly.

        The first signal starts a clean shutdown (running steps get ``step_finish_timeout`` to finish); a
        second makes it hurry (nothing more is waited for, the transport is still closed); a third exits at once.
        """
        stop_if_capturing(self.recipe)  # `agentsctl recipe show`: the recipe is complete here
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

    __enter__ = start

    def __exit__(self, *exc: object) -> None:
        self.stop()
