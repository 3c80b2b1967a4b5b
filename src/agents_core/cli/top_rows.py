"""What ``agentsctl top`` shows: the latest status of each component, read from its ``<name>/status`` topic.

Every component publishes its state, health and figures on ``<name>/status``
(:class:`~agents_core.messages.ComponentStatusMsg`; the figures are the ``stats`` JSON of
:mod:`agents_core.runtime.figures`) at its ``status_rate`` and on every change. :class:`StatusBook`
discovers the components, subscribes to each one's status and keeps the latest as a row. A status
comes from the network: its ``stats`` is decoded bounded (:data:`MAX_STATS_BYTES`), and only numbers
are kept from it.
"""

from __future__ import annotations

import functools
import threading
import time
from typing import Any

from ..errors import AgentsError
from ..runtime.figures import MAX_STATS_BYTES, parse_stats
from ..topics import validate_topic_name
from ..transport.contract import Subscription, Transport
from ..transport.core import status_topic

__all__ = ["COLUMNS", "MAX_STATS_BYTES", "SORT_KEYS", "StatusBook", "parse_stats", "sort_rows"]

#: (header, row key) of each column, in order.
COLUMNS = (("component", "component"), ("state", "state"), ("health", "health"), ("steps/s", "rate_hz"),
           ("p50 ms", "p50_ms"), ("p99 ms", "p99_ms"), ("model ms", "model_ms"), ("drops", "drops"),
           ("restarts", "restarts"), ("cpu %", "cpu_pct"), ("rss MB", "rss_mb"), ("pid", "pid"))
#: Key pressed -> (row key sorted by, highest first).
SORT_KEYS = {"n": ("component", False), "r": ("rate_hz", True), "5": ("p50_ms", True), "9": ("p99_ms", True),
             "m": ("model_ms", True), "d": ("drops", True), "t": ("restarts", True), "c": ("cpu_pct", True),
             "s": ("rss_mb", True)}


def sort_rows(rows: list[dict[str, Any]], key: str) -> list[dict[str, Any]]:
    """Rows sorted by :data:`SORT_KEYS` entry ``key`` (by name for an unknown key); rows without the figure last."""
    field, descending = SORT_KEYS.get(key, SORT_KEYS["n"])
    if field == "component":
        return sorted(rows, key=lambda r: str(r["component"]))
    have = [r for r in rows if isinstance(r.get(field), int | float)]
    lack = sorted((r for r in rows if r not in have), key=lambda r: str(r["component"]))
    return sorted(have, key=lambda r: (r[field], str(r["component"])), reverse=descending) + lack


class StatusBook:
    """The components of the graph ``transport`` sees and the latest status of each (see the module docstring)."""

    def __init__(self, transport: Transport) -> None:
        self._transport = transport
        self._lock = threading.Lock()
        self._rows: dict[str, dict[str, Any]] = {}
        self._subscriptions: dict[str, Subscription] = {}
        self.updates = 0

    def discover(self, timeout: float) -> None:
        """Find the components now in the graph: subscribe to new ones' status, drop those gone."""
        names = set()
        for name in self._transport.discover(timeout=timeout).components:
            try:
                names.add(validate_topic_name(name, "component"))
            except AgentsError:  # a hostile token or a wildcard: never subscribed to
                continue
        for name in sorted(names - set(self._subscriptions)):
            with self._lock:
                self._rows.setdefault(name, {"component": name, "state": "unknown", "health": "unknown"})
            try:
                self._subscriptions[name] = self._transport.create_subscription(
                    status_topic(name), functools.partial(self._on_status, name))
            except AgentsError:
                continue
        for name in sorted(set(self._subscriptions) - names):
            self._subscriptions.pop(name).close()
            with self._lock:
                self._rows.pop(name, None)

    def _on_status(self, name: str, msg: Any) -> None:
        row = {"component": name, "state": str(getattr(msg, "lifecycle_state", "unknown"))[:40],
               "health": str(getattr(msg, "health", "unknown"))[:40], "seen": time.monotonic(),
               **parse_stats(str(getattr(msg, "stats", "") or ""))}
        with self._lock:
            if name in self._rows or name in self._subscriptions:
                self._rows[name] = row
                self.updates += 1

    def rows(self, sort: str = "n") -> list[dict[str, Any]]:
        """A copy of the rows, sorted (:func:`sort_rows`)."""
        with self._lock:
            rows = [dict(r) for r in self._rows.values()]
        for row in rows:
            row.pop("seen", None)
        return sort_rows(rows, sort)

    def waiting(self) -> int:
        """How many discovered components have sent no status yet."""
        with self._lock:
            return sum(1 for r in self._rows.values() if "seen" not in r)

    def close(self) -> None:
        """Close every subscription."""
        for subscription in self._subscriptions.values():
            subscription.close()
        self._subscriptions.clear()
