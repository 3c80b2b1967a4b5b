"""Status lines after start: a component whose state or health changes gets a new row.

:class:`LiveStatus` polls the launcher's components (or, with ``multiprocessing=True``, the
supervisor's children) twice a second on a daemon thread and hands each changed row to the
:class:`~agents_core.launch.report.LaunchReport`, so the person who started the recipe sees a
component fail, recover, crash and respawn ("restart 1/3"), or give up, without reading logs.
Polling, not callbacks: the rows come from three sources (in-process components, child
processes, the supervisor's restart counters) and a poll reads them all the same way, off every
transport and worker thread.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from typing import Any

from .report import LaunchReport, component_row

__all__ = ["LiveStatus", "child_rows", "component_rows"]

#: One component's row: (name, state, health, note).
Row = tuple[str, str, str, str]


def component_rows(components: Sequence[Any]) -> list[Row]:
    """The rows of components running in this process."""
    return [(*component_row(c), "") for c in components]


def child_rows(describe: Callable[[], list[dict[str, Any]]], max_retries: int) -> list[Row]:
    """The rows of component processes, from :meth:`Supervisor.describe`."""
    rows: list[Row] = []
    for child in describe():
        if child.get("gave_up"):
            note = f"gave up after {child.get('restarts', 0)} restart(s)"
        elif child.get("restarts"):
            note = f"own process, pid {child.get('pid')}, restart {child['restarts']}/{max_retries}"
        else:
            note = f"own process, pid {child.get('pid')}"
        rows.append((str(child["name"]), str(child["state"]), str(child.get("health") or "-"), note))
    return rows


class LiveStatus:
    """Report each row of ``rows()`` that differs from the last one seen.

    :param report: where the rows go (a quiet report prints nothing, and then no thread starts).
    :param rows: returns the current rows; called on the poll thread.
    :param interval: seconds between polls.
    """

    def __init__(self, report: LaunchReport, rows: Callable[[], list[Row]], interval: float = 0.5) -> None:
        self._report = report
        self._rows = rows
        self._interval = interval
        self._seen: dict[str, Row] = {}
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Remember the rows as they are now (already printed at start) and watch for changes."""
        if self._report.quiet or self._thread is not None:
            return
        self._seen = {row[0]: row for row in self._safe_rows()}
        self._thread = threading.Thread(target=self._run, name="agents-live-status", daemon=True)
        self._thread.start()

    def poll(self) -> list[Row]:
        """Report and return the rows that changed since the last poll."""
        changed = []
        for row in self._safe_rows():
            if self._seen.get(row[0]) != row:
                self._seen[row[0]] = row
                self._report.component(*row)
                changed.append(row)
        return changed

    def stop(self) -> None:
        """Stop watching (bounded: the poll thread is a daemon and wakes at least every ``interval``)."""
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=2 * self._interval + 1.0)

    def _run(self) -> None:
        while not self._stop.wait(self._interval):
            self.poll()

    def _safe_rows(self) -> list[Row]:
        try:
            return self._rows()
        except Exception:  # a component shutting down mid-read: the next poll sees it settled
            return []
