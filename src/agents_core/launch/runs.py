"""How a recipe's components run: one small interface, :class:`Run`, and its two runs.

- :class:`ThreadRun`: every component in this process, on its own worker thread, bound to the
  launcher's transport;
- :class:`ProcessRun`: a process per component (``add_pkg(multiprocessing=True)``), each built
  from its :class:`~agents_core.launch.spec.ComponentSpec` (the encoding of its recipe entry) by
  the fork server or a fresh interpreter, watched and respawned by the
  :class:`~agents_core.launch.supervisor.Supervisor`.

The :class:`~agents_core.launch.launcher.Launcher` opens the transport, starts one run, the
event wiring (:mod:`.event_wiring`) and the attachments (:mod:`.attachments`), and asks the run
whether everything is active, what each component's status row says and where an action runs.
"""

from __future__ import annotations

import functools
import logging
import os
import sys
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Protocol

from ..components.component_base import Component
from ..errors import ComponentError
from ..events import Event
from ..status import LifecycleState
from .live_status import Row, child_rows, component_rows
from .preflight import LIFECYCLE_METHODS, check_remote_action
from .report import LaunchReport, component_row

if TYPE_CHECKING:
    from ..actions import Action
    from ..transport.contract import Transport
    from .event_wiring import EventWiring
    from .fork_server import ForkServer
    from .recipe import Recipe
    from .supervisor import Supervisor

__all__ = ["ProcessRun", "Run", "ThreadRun", "prepare_fork_server"]

logger = logging.getLogger("agents_core.launch.launcher")


class Run(Protocol):
    """The few methods a launcher needs of the way its components run."""

    def start(self, failing: list[tuple[str | None, str]]) -> None:
        """Bring every component up (``failing[0]``: which one and at what stage, should it fail)."""
        ...

    def stop(self) -> None:
        """Take every component down (before the transport closes)."""
        ...

    def after_transport_closed(self) -> None:
        """Clean up what only the closed transport released."""
        ...

    def all_active(self) -> bool:
        """Every component is in the active state."""
        ...

    def status_rows(self) -> list[Row]:
        """One status row per component (:mod:`.live_status`)."""
        ...

    def call_action(self, action: Action, values: Mapping[str, Any]) -> Any:
        """Run ``action`` (an event's, a give-up's) where it belongs; its result."""
        ...

    def dispatch(self, action: Action, job: Callable[[], None]) -> bool:
        """Queue ``job`` (which runs ``action``) on its component's own worker, if the run has one here."""
        ...


class ThreadRun:
    """Every component in this process (see the module docstring)."""

    def __init__(self, recipe: Recipe, transport: Transport, wiring: EventWiring, report: LaunchReport) -> None:
        self._components = list(recipe.components)
        self._transport = transport
        self._wiring = wiring
        self._report = report

    def start(self, failing: list[tuple[str | None, str]]) -> None:
        for c in self._components:
            c.runtime.bind(self._transport)
        self._wiring.watch(self._transport)
        for c in self._components:
            failing[0] = (c.component_name, "configure")
            c.configure()
        for c in self._components:
            failing[0] = (c.component_name, "activate")
            c.activate()
            self._report.component(*component_row(c))

    def stop(self) -> None:
        for c in reversed(self._components):
            if not c.runtime.is_bound:
                continue
            try:
                c.shutdown()
            except Exception as exc:
                logger.warning("component %r did not shut down cleanly: %s", c.component_name, exc)

    def after_transport_closed(self) -> None:
        return None

    def all_active(self) -> bool:
        return all(c.lifecycle_state == LifecycleState.ACTIVE for c in self._components)

    def status_rows(self) -> list[Row]:
        return component_rows(self._components)

    def call_action(self, action: Action, values: Mapping[str, Any]) -> Any:
        return action(values)

    def dispatch(self, action: Action, job: Callable[[], None]) -> bool:
        owner = action.owner
        if isinstance(owner, Component) and owner.runtime.is_bound:
            owner.runtime.submit_action(job)
            return True
        return False


class ProcessRun:
    """A process per component (see the module docstring).

    A child opens its transport with what the transport says reaches it from another process
    (``peer_process_options``), else with the recipe's transport options. Once a component's
    process crashed more often than ``on_process_fail`` allows, the give-up is logged and the
    recipe's ``on_giveup`` action runs on the launcher's action worker.
    """

    def __init__(self, recipe: Recipe, transport: Transport, wiring: EventWiring, report: LaunchReport, *,
                 fork_server: ForkServer | None) -> None:
        self._recipe = recipe
        self._transport = transport
        self._wiring = wiring
        self._report = report
        self._fork_server = fork_server
        self.supervisor: Supervisor | None = None
        self._stopped: Supervisor | None = None

    def start(self, failing: list[tuple[str | None, str]]) -> None:
        from .spec import ComponentSpec, check_rebuild  # noqa: PLC0415
        from .supervisor import Supervisor  # noqa: PLC0415

        transport = self._transport
        # A transport may say how another process reaches it (Zenoh: connect to this session's
        # listening endpoints); by default ({}) a child opens it with the same options.
        options = transport.peer_process_options() or dict(self._recipe.settings.transport_options)
        specs = []
        for entry in self._recipe.entries():
            spec = ComponentSpec.from_entry(entry, transport.name, options, os.getpid())
            spec.namespace = self._recipe.settings.namespace
            check_rebuild(entry.component, spec)
            specs.append(spec)
        for event, actions in self._recipe.events_actions.items():
            for action in actions:
                check_remote_action(event, action)
        retries = self._recipe.settings.process_fail_retries
        supervisor = Supervisor(specs, max_retries=retries if retries is not None else 0, on_giveup=self._gave_up_on,
                                fork_server=self._fork_server)
        self.supervisor = supervisor
        for c in self._recipe.components:
            if isinstance(c.trigger, Event):
                self._wiring.listen(c.trigger, functools.partial(_forward_trigger, supervisor, c.component_name))
        supervisor.start()
        self._wiring.watch(transport)
        for row in supervisor.describe():
            self._report.component(str(row["name"]), str(row["state"]), "-", f"own process, pid {row['pid']}")

    def _gave_up_on(self, component_name: str) -> None:
        retries = self._recipe.settings.process_fail_retries
        if retries is None:
            logger.error("component %r: its process crashed; not restarting it (launcher.on_process_fail("
                         "max_retries) respawns crashed components)", component_name)
        else:
            logger.error("component %r: its process crashed more often than on_process_fail(max_retries=%d) "
                         "allows; not restarting it", component_name, retries)
        action = self._recipe.settings.process_giveup
        if action is not None:
            self._wiring.submit(functools.partial(self._wiring.run_action, action, {}, "on_giveup"))

    def stop(self) -> None:
        supervisor, self.supervisor = self.supervisor, None
        if supervisor is not None:
            supervisor.stop()
            self._stopped = supervisor

    def after_transport_closed(self) -> None:
        stopped, self._stopped = self._stopped, None
        if stopped is not None:
            # This process may have mapped a crashed child's segment until its transport closed.
            stopped.remove_orphan_shm()

    def all_active(self) -> bool:
        return self.supervisor is not None and self.supervisor.all_active()

    def status_rows(self) -> list[Row]:
        supervisor = self.supervisor
        if supervisor is None:
            return []
        return child_rows(supervisor.describe, supervisor.max_retries)

    def call_action(self, action: Action, values: Mapping[str, Any]) -> Any:
        """An action on a component runs through its services (lifecycle, ``execute_method``); another one here."""
        owner = action.owner
        if not isinstance(owner, Component):
            return action(values)
        args, kwargs = action.resolve(values)
        name = action.name
        if name in LIFECYCLE_METHODS:
            if not self._transport.request_transition(owner.component_name, name, timeout=10.0):
                raise ComponentError(f"component {owner.component_name!r} refused the transition {name!r}")
            return None
        reply = self._transport.request(f"{owner.component_name}/execute_method",
                                        {"method": name, "args": list(args), "kwargs": kwargs}, timeout=30.0)
        return reply.get("result")

    def dispatch(self, action: Action, job: Callable[[], None]) -> bool:
        return False  # the launcher's action worker sends it


def prepare_fork_server(recipe: Recipe) -> ForkServer | None:
    """Start (or reuse) the fork server and have it import what the component processes need (None: not needed)."""
    settings = recipe.settings
    recipe_import = sys.modules.get("agents_core.launch.recipe_import")
    if not settings.multiprocessing or settings.process_start != "fork" or (
            recipe_import is not None and recipe_import.importing_recipe()):
        return None  # a component process importing its recipe never starts a server
    from .fork_server import adapter_module, prepare  # noqa: PLC0415 - multiprocessing only

    return prepare({type(c).__module__ for c in recipe.components}, sys.path, adapter_module(settings.transport))


def _forward_trigger(supervisor: Supervisor, component_name: str, event: Event, values: Mapping[str, Any]) -> None:
    """The trigger event of a component in its own process fired here: fire its stand-in there."""
    if not supervisor.child(component_name).send("fire-trigger"):
        logger.debug("component %r is not running: trigger event %r dropped", component_name, event.name)
