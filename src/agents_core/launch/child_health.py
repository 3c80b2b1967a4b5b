"""A component process tells the launcher its health, as it tells it its lifecycle state.

The launcher's status rows show each component's state and health; for a component in its own process it
only had the state (the health showed as ``-``). :func:`report_health` runs on a thread of the component's
process: it sends ``{"health": "<name, lower case>"}`` down the report pipe at once and again whenever
the health changes (checked every :data:`HEALTH_POLL_S`), until ``stop`` is set.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

__all__ = ["HEALTH_POLL_S", "start_health_reports"]

#: How often the component's health is compared with the last one sent.
HEALTH_POLL_S = 0.25


def _report(component: Any, send: Callable[..., None], stop: threading.Event, last: str) -> None:
    while True:
        health = component.health_status.name.lower()
        if health != last:
            send(health=health)
            last = health
        if stop.wait(HEALTH_POLL_S):
            return


def start_health_reports(component: Any, send: Callable[..., None]) -> threading.Event:
    """Start reporting ``component``'s health with ``send(health=...)``; set the returned event to stop."""
    stop = threading.Event()
    first = component.health_status.name.lower()
    send(health=first)  # at once, before any command: the first row shows it
    threading.Thread(target=_report, args=(component, send, stop, first), name="health-reports",
                     daemon=True).start()
    return stop
