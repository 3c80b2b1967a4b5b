"""The Cortex as the system monitor: the health of every component it knows, from their status topics.

Each component publishes its lifecycle state and health on ``<name>/status``. The watch keeps
the latest of each, logs changes, and answers whether a component a task depends on has failed:
a failure health (``ALGORITHM_FAILURE``, ``COMPONENT_FAILURE``, ``SYSTEM_FAILURE``) or a
lifecycle state in which it cannot act (``finalized``, ``error``, ``inactive`` after having been
active).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any

from ...transport.core import status_topic

if TYPE_CHECKING:
    from ...transport.contract import Subscription, Transport

__all__ = ["HealthWatch"]

_FAILED_STATES = frozenset({"finalized", "error"})


class HealthWatch:
    """Latest status of each watched component (see the module docstring)."""

    def __init__(self, logger: logging.Logger) -> None:
        self._logger = logger
        self._lock = threading.Lock()
        self._status: dict[str, tuple[str, str, str]] = {}  # name -> (state, health, message)
        self._was_active: set[str] = set()
        self._subscriptions: dict[str, Subscription] = {}
        self._listeners: list[Callable[[str, str, str, str], None]] = []
        #: Status changes seen (any component).
        self.changes = 0

    def watch(self, transport: Transport, names: Iterable[str], owner: str) -> None:
        """Subscribe to the status topics of ``names`` not watched yet."""
        for name in names:
            with self._lock:
                if name in self._subscriptions:
                    continue
            sub = transport.create_subscription(status_topic(name), self._on_status, owner=owner)
            with self._lock:
                self._subscriptions[name] = sub

    def add_listener(self, listener: Callable[[str, str, str, str], None]) -> None:
        """Call ``listener(component, state, health, message)`` on each status change."""
        self._listeners.append(listener)

    def _on_status(self, msg: Any) -> None:
        name = str(getattr(msg, "component", ""))
        entry = (str(getattr(msg, "lifecycle_state", "")), str(getattr(msg, "health", "")),
                 str(getattr(msg, "message", "")))
        with self._lock:
            previous = self._status.get(name)
            self._status[name] = entry
            if entry[0] == "active":
                self._was_active.add(name)
            if previous == entry:
                return
            self.changes += 1
        level = logging.INFO if entry[1] == "HEALTHY" else logging.WARNING
        self._logger.log(level, "component %r is %s, %s%s", name, entry[0], entry[1],
                         f": {entry[2]}" if entry[2] else "")
        for listener in list(self._listeners):
            listener(name, *entry)

    def status(self) -> dict[str, dict[str, str]]:
        """``{component: {"state", "health", "message"}}`` as last seen."""
        with self._lock:
            return {n: {"state": s, "health": h, "message": m} for n, (s, h, m) in self._status.items()}

    def failure(self, component: str) -> str | None:
        """Why ``component`` cannot be relied on now, or None when it is fine (or not heard from yet)."""
        with self._lock:
            entry = self._status.get(component)
            was_active = component in self._was_active
        if entry is None:
            return None
        state, health, message = entry
        if health and health != "HEALTHY":
            return f"component {component!r} reports {health}" + (f": {message}" if message else "")
        if state in _FAILED_STATES or (state == "inactive" and was_active):
            return f"component {component!r} is {state}"
        return None

    def first_failure(self, components: Iterable[str]) -> str | None:
        """The first reason any of ``components`` has failed, or None."""
        for name in components:
            reason = self.failure(name)
            if reason is not None:
                return reason
        return None

    def close(self) -> None:
        """Stop watching (subscriptions closed; the last statuses are kept)."""
        with self._lock:
            subs, self._subscriptions = list(self._subscriptions.values()), {}
        for sub in subs:
            try:
                sub.close()
            except Exception as exc:  # closing at teardown: the transport may be gone already
                self._logger.debug("status subscription not closed: %s", exc)
