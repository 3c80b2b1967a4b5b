"""The progress of an evaluation as its episodes finish: a bar on a terminal, a line per episode elsewhere.

On a terminal (``stream.isatty()``) one line is redrawn in place (carriage return, then erase to
the end of the line), never wider than the terminal so that it never wraps::

    episodes 7/20 [#######-------------]  success 5/7 (71 %)  0:42 left

Anywhere else (a CI log, a file, a pipe) each finished episode prints its own line, and nothing
is redrawn::

    episode 7/20: success  (5/7 succeeded, 71 %)  0:42 left

The time left is the time elapsed per finished episode times the episodes still to run, so
episodes that run in parallel count at the rate they actually finish. Plain text only: the core
does not need Rich. Calls may come from several threads.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Callable
from typing import TextIO

__all__ = ["EpisodeProgress", "format_duration"]

_BAR_WIDTH = 20
_ERASE_TO_END = "\x1b[K"


def format_duration(seconds: float) -> str:
    """``seconds`` as ``m:ss`` or ``h:mm:ss`` (``?`` when not known)."""
    if not seconds >= 0 or seconds == float("inf"):
        return "?"
    total = round(seconds)
    hours, rest = divmod(total, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


class EpisodeProgress:
    """Shows episodes done out of ``total``, the successes so far with their rate, and the time left, on ``stream``.

    Call :meth:`episode_done` as each episode ends and :meth:`close` once at the end (also after
    Ctrl-C: it ends the bar's line and prints the summary). ``clock`` is for tests.
    """

    def __init__(self, total: int, stream: TextIO | None = None, *,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if isinstance(total, bool) or not isinstance(total, int) or total < 0:
            raise ValueError(f"EpisodeProgress total must be an int >= 0, got {total!r}")
        self.total = total
        self.stream = sys.stderr if stream is None else stream
        self._clock = clock
        self._started = clock()
        self._lock = threading.Lock()
        self.done = 0
        self.successes = 0
        self.wall_s = 0.0
        self._closed = False
        self.tty = _is_tty(self.stream)
        if self.tty:
            self._draw(self._bar_line())

    @property
    def rate(self) -> float:
        """The success rate so far (0.0 before the first episode)."""
        return self.successes / self.done if self.done else 0.0

    def seconds_left(self) -> float | None:
        """The estimated time to the last episode (None before the first one ends)."""
        if not self.done:
            return None
        elapsed = self._clock() - self._started
        return max(0.0, elapsed / self.done * max(0, self.total - self.done))

    def episode_done(self, success: bool, wall_s: float) -> None:
        """Count one finished episode (``wall_s``: its own wall time) and show the new state."""
        with self._lock:
            if self._closed:
                return
            self.done += 1
            self.successes += 1 if success else 0
            self.wall_s += float(wall_s)
            if self.tty:
                self._draw(self._bar_line())
            else:
                self._write(f"episode {self.done}/{self.total}: {'success' if success else 'failure'}  "
                            f"({self.successes}/{self.done} succeeded, {_percent(self.rate)})  "
                            f"{self._left_text()}\n")

    def close(self) -> None:
        """End the bar (a newline on a terminal) and print the summary line; further calls do nothing."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            elapsed = self._clock() - self._started
            if self.tty:
                self._draw(self._bar_line(final=True))
                self._write("\n")
            stopped = "" if self.done >= self.total else f" (stopped: {self.total - self.done} not run)"
            self._write(f"{self.done}/{self.total} episodes in {format_duration(elapsed)}: {self.successes} "
                        f"succeeded ({_percent(self.rate)}){stopped}\n")

    def _left_text(self) -> str:
        left = self.seconds_left()
        return "time left ?" if left is None else f"{format_duration(left)} left"

    def _bar_line(self, final: bool = False) -> str:
        filled = _BAR_WIDTH if not self.total else min(_BAR_WIDTH, _BAR_WIDTH * self.done // self.total)
        bar = "#" * filled + "-" * (_BAR_WIDTH - filled)
        tail = "" if final else f"  {self._left_text()}"
        return (f"episodes {self.done}/{self.total} [{bar}]  success {self.successes}/{self.done} "
                f"({_percent(self.rate)}){tail}")

    def _draw(self, line: str) -> None:
        width = _terminal_width(self.stream)
        self._write("\r" + line[: max(1, width - 1)] + _ERASE_TO_END)

    def _write(self, text: str) -> None:
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):  # a closed stream (the terminal went away) must not end the evaluation
            pass


def _percent(rate: float) -> str:
    return f"{rate * 100:.0f} %"


def _is_tty(stream: TextIO) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


def _terminal_width(stream: TextIO) -> int:
    try:
        return os.get_terminal_size(stream.fileno()).columns or 80
    except (AttributeError, ValueError, OSError):
        return 80
