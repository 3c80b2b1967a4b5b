"""The launcher's events: one subscription per event topic, each firing's actions run where they belong.

Every event of ``events_actions`` and every component trigger event is evaluated here, in the
launcher's process: :meth:`EventWiring.watch` subscribes to each event's topics and feeds the
values to the event. A firing runs its actions through the run (:class:`~agents_core.launch.runs.Run`):
in a run in this process, an action on a component's method runs on that component's worker; any
other action (and every action of a process-per-component run, which goes through the component's
services) runs on the launcher's own action worker, one at a time.
"""

from __future__ import annotations

import functools
import logging
import threading
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Protocol

from ..actions import Action
from ..events import Event, EventListener
from ..runtime.worker import StepWorker

if TYPE_CHECKING:
    from ..transport.contract import Subscription, Transport
    from .recipe import Recipe

__all__ = ["ActionRunner", "EventWiring"]

logger = logging.getLogger("agents_core.launch.launcher")


class ActionRunner(Protocol):
    """What the wiring needs of a run (:class:`~agents_core.launch.runs.Run` has it)."""

    def call_action(self, action: Action, values: Mapping[str, Any]) -> Any:
        """Run ``action`` where it belongs."""
        ...

    def dispatch(self, action: Action, job: Callable[[], None]) -> bool:
        """Queue ``job`` on its component's own worker, if there is one here."""
        ...


def _feed_event(event: Event, topic_name: str, value: Any) -> None:
    event.process(topic_name, value)


class EventWiring:
    """The event listeners, subscriptions and action worker of one launch."""

    def __init__(self, recipe: Recipe, hurry: threading.Event) -> None:
        self._recipe = recipe
        self._hurry = hurry
        self._run: ActionRunner | None = None
        self._worker: StepWorker | None = None
        self._subscriptions: list[Subscription] = []
        self._listeners: list[tuple[Event, EventListener]] = []

    def arm(self, run: ActionRunner) -> None:
        """Start the action worker and listen to every event of ``events_actions`` (actions through ``run``)."""
        self._run = run
        self._worker = StepWorker("launcher-actions", 1, "drop_newest")
        for event, actions in self._recipe.events_actions.items():
            self.listen(event, self._runner(actions))

    def listen(self, event: Event, listener: EventListener) -> None:
        """Add ``listener`` to ``event`` until :meth:`disarm`."""
        event.add_listener(listener)
        self._listeners.append((event, listener))

    def watch(self, transport: Transport) -> None:
        """Subscribe to the topics of every event the launcher evaluates."""
        for event in self._recipe.watched_events():
            for topic in event.topics.values():
                self._subscriptions.append(transport.create_subscription(
                    topic, functools.partial(_feed_event, event, topic.name)))

    def submit(self, job: Callable[[], None]) -> None:
        """Run ``job`` on the launcher's action worker (dropped once it is stopped)."""
        if self._worker is not None:
            self._worker.submit_control(job)

    def run_action(self, action: Action, values: Mapping[str, Any], what: str) -> None:
        """Run ``action`` through the run, logging (with ``what``) instead of raising."""
        try:
            if self._run is not None:
                self._run.call_action(action, values)
        except Exception:
            logger.exception("action %s for %s failed", action.name, what)

    def _runner(self, actions: list[Action]) -> EventListener:
        def run(event: Event, values: Mapping[str, Any]) -> None:
            for action in actions:
                job = functools.partial(self.run_action, action, values, f"event {event.name!r}")
                if self._run is None or not self._run.dispatch(action, job):
                    self.submit(job)

        return run

    def close_subscriptions(self) -> None:
        """Close the subscriptions and remove the listeners (before the components stop)."""
        for sub in self._subscriptions:
            sub.close()
        self._subscriptions.clear()
        for event, listener in self._listeners:
            event.remove_listener(listener)
        self._listeners.clear()

    def disarm(self) -> None:
        """Stop the action worker (hurried by the launcher's hurry event)."""
        if self._worker is not None:
            self._worker.stop(timeout=2.0, abort=self._hurry)
            self._worker = None
