"""Events: something observed on topics (or raised by code) that fires actions or component steps.

- ``Event(event_condition=topic)`` fires on every message of ``topic``;
- ``Event(event_condition=topic.msg.data > 0.5)`` fires on each message for which the condition
  holds (conditions may combine fields with ``&``, ``|``, ``~``; see :mod:`agents_core.conditions`);
- ``Event(name="...")`` with no condition fires only when code calls :meth:`Event.trigger`.

Options: ``on_change`` fires only when the condition turns true (or, for a bare topic, when
the value changes), ``handle_once`` fires at most once, and ``keep_event_delay`` is the
minimum time in seconds between two firings.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any

from .conditions import Condition
from .errors import ConfigError
from .topics import Topic, validate_topic_name
from .types.fields import values_equal

__all__ = ["Event", "EventListener"]

logger = logging.getLogger(__name__)

#: Called with the event and the latest value of each of its topics when it fires.
EventListener = Callable[["Event", Mapping[str, Any]], None]

_counter = 0
_counter_lock = threading.Lock()


def _auto_name() -> str:
    global _counter  # noqa: PLW0603  # a process-wide sequence for unnamed events
    with _counter_lock:
        _counter += 1
        return f"event_{_counter}"


class Event:
    """A named occurrence that components and the launcher can react to."""

    def __init__(
        self,
        name: str | Topic | Condition | None = None,
        event_condition: Topic | Condition | None = None,
        *,
        on_change: bool = False,
        handle_once: bool = False,
        keep_event_delay: float = 0.0,
    ) -> None:
        if isinstance(name, Topic | Condition) and event_condition is None:
            name, event_condition = None, name
        self.name = validate_topic_name(name, "event") if name is not None else _auto_name()
        if event_condition is not None and not isinstance(event_condition, Topic | Condition):
            raise ConfigError(
                f"event {self.name!r}: event_condition must be a Topic or a condition such as "
                f"topic.msg.data > 1, got {type(event_condition).__name__}"
            )
        if isinstance(keep_event_delay, bool) or not isinstance(keep_event_delay, int | float) or keep_event_delay < 0:
            raise ConfigError(f"event {self.name!r}: keep_event_delay must be >= 0 seconds, got {keep_event_delay!r}")
        self.event_condition = event_condition
        self.on_change = on_change
        self.handle_once = handle_once
        self.keep_event_delay = float(keep_event_delay)
        self._lock = threading.Lock()
        self._listeners: list[EventListener] = []
        self._values: dict[str, Any] = {}
        self._last_state: Any = None
        self._fired = 0
        self._last_fire = -float("inf")

    @property
    def topics(self) -> dict[str, Topic]:
        """The topics whose messages this event watches, by name."""
        if isinstance(self.event_condition, Topic):
            return {self.event_condition.name: self.event_condition}
        if isinstance(self.event_condition, Condition):
            return dict(self.event_condition.topics)
        return {}

    @property
    def fired(self) -> int:
        """How many times the event fired."""
        return self._fired

    def add_listener(self, listener: EventListener) -> None:
        """Call ``listener(event, values)`` whenever the event fires."""
        with self._lock:
            if listener not in self._listeners:
                self._listeners.append(listener)

    def remove_listener(self, listener: EventListener) -> None:
        """Stop calling ``listener``."""
        with self._lock:
            if listener in self._listeners:
                self._listeners.remove(listener)

    def process(self, topic_name: str, value: Any) -> bool:
        """Feed a received message; fires the event if its condition says so. Returns whether it fired."""
        with self._lock:
            self._values[topic_name] = value
            values = dict(self._values)
            cond = self.event_condition
            if isinstance(cond, Condition):
                state: Any = cond.evaluate(values)
                changed = state != self._last_state
                self._last_state = state
                should = bool(state) and (changed or not self.on_change)
            else:
                changed = self._last_state is None or not values_equal(value, self._last_state)
                self._last_state = value
                should = changed or not self.on_change
        return self._fire(values) if should else False

    def trigger(self, values: Mapping[str, Any] | None = None) -> bool:
        """Fire the event from code (subject to ``handle_once`` and ``keep_event_delay``)."""
        return self._fire(dict(values or {}))

    def _fire(self, values: Mapping[str, Any]) -> bool:
        with self._lock:
            now = time.monotonic()
            if self.handle_once and self._fired:
                return False
            if now - self._last_fire < self.keep_event_delay:
                return False
            self._fired += 1
            self._last_fire = now
            listeners = list(self._listeners)
        for listener in listeners:
            try:
                listener(self, values)
            except Exception:
                logger.exception("a listener of event %r raised", self.name)
        return True

    def reset(self) -> None:
        """Forget the values seen and the firing history (``handle_once`` can fire again)."""
        with self._lock:
            self._values.clear()
            self._last_state = None
            self._fired = 0
            self._last_fire = -float("inf")

    def __repr__(self) -> str:
        cond = self.event_condition
        what = repr(cond) if cond is not None else "manual"
        return f"Event({self.name!r}, {what})"
