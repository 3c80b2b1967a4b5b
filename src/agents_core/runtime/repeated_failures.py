"""Saying a repeated failure once, then counting it: the log of a step that fails at every step.

A component whose step fails the same way at 2 Hz would log the same line twice a second (about 160 lines
in 80 s) and bury everything else. :class:`RepeatedFailures` lets the first occurrence of a failure through,
counts the identical ones that follow, and says how many there were: every :data:`SUMMARY_EVERY_S` seconds
while it goes on, when a different failure comes, when the component recovers, and when it stops. A different failure is
always logged at once. With the component's logger at DEBUG every failure is logged, with its traceback.
"""

from __future__ import annotations

import logging
import threading
import time

__all__ = ["SUMMARY_EVERY_S", "RepeatedFailures"]

#: How often a failure that goes on is summarised ("... N more times in the last 30 s").
SUMMARY_EVERY_S = 30.0


class RepeatedFailures:
    """Decides which failure lines a component logs (see the module docstring)."""

    def __init__(self, logger: logging.Logger, summary_every_s: float | None = None) -> None:
        self._logger = logger
        self._every = summary_every_s if summary_every_s is not None else SUMMARY_EVERY_S
        self._lock = threading.Lock()
        self._key: tuple[str, ...] | None = None
        self._line = ""
        self._repeats = 0
        self._since = 0.0

    def should_log(self, key: tuple[str, ...], line: str) -> bool:
        """Whether to log this failure (``key`` says which failures are the same); counts it when not."""
        if self._logger.isEnabledFor(logging.DEBUG):
            return True
        with self._lock:
            now = time.monotonic()
            if key == self._key:
                self._repeats += 1
                if now - self._since >= self._every:
                    self._summary_locked(now, "so far")
                return False
            self._summary_locked(now, "before a different failure")
            self._key, self._line, self._repeats, self._since = key, line, 0, now
            return True

    def recovered(self) -> None:
        """The component is healthy again: say how often the last failure repeated, and forget it."""
        self._forget("before recovering")

    def stopped(self) -> None:
        """The component stops (deactivates) while failing: say how often, and forget it (a new start says the
        failure again)."""
        self._forget("before stopping")

    def _forget(self, when: str) -> None:
        with self._lock:
            self._summary_locked(time.monotonic(), when)
            self._key = None

    def _summary_locked(self, now: float, when: str) -> None:
        if self._key is not None and self._repeats:
            self._logger.error("%s: %d more time(s) in the last %.0f s (%s)", self._line, self._repeats,
                               now - self._since, when)
        self._repeats, self._since = 0, now
