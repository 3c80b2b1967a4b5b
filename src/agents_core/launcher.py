"""``Launcher``: runs a recipe's components on a transport.

Blocking, for a robot::

    launcher = Launcher(transport="zenoh")      # None reads AGENTS_TRANSPORT (default "memory")
    launcher.add_pkg(components=[llm, vision], events_actions={low_battery: Action(llm.deactivate)})
    launcher.bringup()                          # until SIGINT / SIGTERM, then a clean shutdown

Non-blocking, for tests and embedding::

    with Launcher(transport="memory") as launcher:   # start() on enter, stop() on exit
        pub = launcher.transport.create_publisher(Topic("question", "String"))
        pub.publish("hello")

The launcher watches every event used by a component trigger or in ``events_actions`` with one
subscription per event topic, and runs each action on the worker of the component that owns
the method (or on the launcher's own action worker for other callables).
"""

from __future__ import annotations

import functools
import logging
import os
import signal
import threading
from collections.abc import Mapping, Sequence
from types import FrameType
from typing import Any

from .actions import Action
from .components.component_base import Component
from .components.worker import StepWorker
from .errors import ConfigError, WiringError
from .events import Event, EventListener
from .status import LifecycleState
from .transport.contract import Subscription, Transport
from .transport.registry import resolve_transport

__all__ = ["Launcher"]

logger = logging.getLogger(__name__)


def _feed_event(event: Event, topic_name: str, value: Any) -> None:
    event.process(topic_name, value)


class Launcher:
    """Brings up components on a transport and takes them down cleanly.

    :param transport: a transport name (``"memory"``, ``"zenoh"``, ``"ros2"``), a transport
        object, or None to read ``AGENTS_TRANSPORT``.
    :param transport_options: keyword options for the transport's constructor (with a name).
    """

    def __init__(self, transport: str | Transport | None = None, *,
                 transport_options: Mapping[str, Any] | None = None) -> None:
        self._transport_spec = transport
        self._transport_options = dict(transport_options or {})
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
        self._multiprocessing = False

    # -- recipe -------------------------------------------------------------------------------

    def add_pkg(
        self,
        components: Sequence[Component],
        events_actions: Mapping[Event, Action | Sequence[Action]] | None = None,
        multiprocessing: bool = False,
        package_name: str | None = None,
    ) -> None:
        """Add components (and event -> action wiring) to launch.

        ``multiprocessing=True`` (one process per component) needs a transport whose capabilities
        say ``cross_process``; the memory transport, which lives in one process, is refused at start.
        ``package_name`` is accepted for upstream recipes (ROS packages) and not needed here. Any
        other argument is refused, as components refuse theirs.
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
        for event, actions in (events_actions or {}).items():
            if not isinstance(event, Event):
                raise WiringError(f"events_actions keys must be Event objects, got {type(event).__name__}")
            action_list = [actions] if isinstance(actions, Action) else list(actions)
            for a in action_list:
                if not isinstance(a, Action):
                    raise WiringError(f"event {event.name!r}: {a!r} is not an Action")
            self.events_actions.setdefault(event, []).extend(action_list)

    def on_process_fail(self, max_retries: int = 3) -> None:
        """How often to respawn a crashed component process (multiprocessing runs)."""
        self._process_fail_retries = max_retries

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
        self._transport = resolve_transport(self._transport_spec, **self._transport_options)
        self._owns_transport = isinstance(self._transport_spec, str) or self._transport_spec is None
        if self._multiprocessing:
            transport = self._transport
            if self._owns_transport:
                transport.close()
            self._transport = None
            if not transport.capabilities.cross_process:
                raise ConfigError(f"multiprocessing=True needs a transport that reaches across processes "
                                  f"(zenoh or ros2); {transport.name!r} lives in one process")
            raise ConfigError(f"multiprocessing=True is not available yet on {transport.name!r}: run the components "
                              "in this process (multiprocessing=False)")
        self._started = True
        try:
            self._action_worker = StepWorker("launcher-actions", 1, "drop_newest")
            for event, actions in self.events_actions.items():
                runner = self._make_event_runner(actions)
                event.add_listener(runner)
                self._event_runners.append((event, runner))
            for c in self.components:
                c.runtime.bind(self._transport)
            self._watch_events()
            for c in self.components:
                c.configure()
            for c in self.components:
                c.activate()
        except BaseException:
            self.stop()
            raise
        logger.info("launched %d component(s) on %s", len(self.components), self._transport.name)
        return self

    def _watch_events(self) -> None:
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
                if isinstance(owner, Component) and owner.runtime.is_bound:
                    owner.runtime.submit_action(job)
                elif self._action_worker is not None:
                    self._action_worker.submit_control(job)

        return run

    @staticmethod
    def _run_action(event: Event, action: Action, values: Mapping[str, Any]) -> None:
        try:
            action(values)
        except Exception:
            logger.exception("action %s for event %r failed", action.name, event.name)

    def stop(self) -> None:
        """Deactivate and shut down every component, then close the transport if the launcher made it.

        The transport is closed whatever happens before (a component that fails to stop, an
        interrupt): its threads and shared-memory segments must not outlive the recipe.
        """
        try:
            for sub in self._event_subscriptions:
                sub.close()
            self._event_subscriptions.clear()
            for event, runner in self._event_runners:
                event.remove_listener(runner)
            self._event_runners.clear()
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
            if self._transport is not None and self._owns_transport:
                self._transport.close()
            self._started = False

    def hurry(self) -> None:
        """Make a running or coming :meth:`stop` stop waiting for components' running steps."""
        self._hurry.set()
        for c in self.components:
            c.runtime.hurry()

    def all_active(self) -> bool:
        """True when every component is in the active state."""
        return all(c.lifecycle_state == LifecycleState.ACTIVE for c in self.components)

    def bringup(self) -> None:
        """Start, run until SIGINT / SIGTERM (or :meth:`request_stop`), then stop cleanly.

        The first signal starts a clean shutdown (running steps get ``step_finish_timeout`` to
        finish); a second one makes it hurry (nothing more is waited for, the transport is still
        closed); a third exits the process at once with status 128 + the signal number.
        """
        previous: dict[signal.Signals, Any] = {}
        received = 0

        def handler(signum: int, frame: FrameType | None) -> None:
            nonlocal received
            received += 1
            if received == 1:
                logger.info("received signal %d, shutting down (again to hurry, a third time to exit at once)",
                            signum)
                self._stop_requested.set()
            elif received == 2:
                logger.warning("received signal %d again: not waiting for running steps any longer", signum)
                self._stop_requested.set()
                self.hurry()
            else:
                os._exit(128 + signum)

        # Handlers first: a signal that arrives while components start still ends in a clean stop.
        # They stay installed until stop() has returned, so a repeated Ctrl-C never raises
        # KeyboardInterrupt in the middle of the shutdown.
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                previous[sig] = signal.signal(sig, handler)
        try:
            self.start()
            while not self._stop_requested.wait(0.5):
                pass
        finally:
            try:
                self.stop()
            finally:
                for sig, old in previous.items():
                    signal.signal(sig, old)

    def request_stop(self) -> None:
        """Make :meth:`bringup` return (thread-safe)."""
        self._stop_requested.set()

    def __enter__(self) -> Launcher:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
