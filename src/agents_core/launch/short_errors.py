"""One line for a recipe that cannot start, and the traceback only when asked for.

When :meth:`Launcher.bringup` fails with one of the framework's errors (a config, a wiring, a component
that failed to configure), the status lines have already said which component and why; Python's
traceback after them (25 to 112 lines through the launcher and the lifecycle) adds nothing for the
person running the recipe. :func:`short_errors` prints ``agents: error: <message>`` on stderr (or, when
the status lines already showed that reason, ``agents: could not start (the reason is above; ...)``) and
exits with status 1 instead. The traceback is shown, as before, when it is asked for:
``AGENTS_DEBUG=1`` (what ``agentsctl run --debug`` sets), or the ``agents_core`` logger (or the root
logger) at DEBUG level. Errors that are not the framework's (a bug) always keep their traceback, and so does
a framework error caused by one that is not (a bug in a component's own code, wrapped in a ``LifecycleError``
by the lifecycle): its file and line are what the person needs.

A recipe written ``with launcher:`` (the tutorial's form) has no such block around it: the error leaves the
user's script. :func:`one_line_if_uncaught` (called when a start failure is reported) makes Python's handler of
an uncaught exception print the same one line for a framework error whose reason the status lines showed; a
caller that catches the error (a test) sees it unchanged, and anything else keeps its traceback. It shortens
only in front of the interpreter's own handler (``sys.__excepthook__``): a hook installed before the launch
(a crash reporter, the user's logging) gets every uncaught error, as without this module.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
from collections.abc import Callable, Iterator
from types import TracebackType
from typing import Any

from ..errors import AgentsError
from .report import already_reported

__all__ = ["DEBUG_ENV_VAR", "caused_by_a_bug", "debug_requested", "one_line_if_uncaught", "short_errors"]

#: Set to 1 / true / yes for the full traceback of a recipe that fails to start.
DEBUG_ENV_VAR = "AGENTS_DEBUG"


def debug_requested() -> bool:
    """Whether ``AGENTS_DEBUG`` is set, or the ``agents_core`` (or root) logger is at DEBUG level."""
    if os.environ.get(DEBUG_ENV_VAR, "").strip().lower() in ("1", "true", "yes", "on"):
        return True
    return logging.getLogger("agents_core").getEffectiveLevel() <= logging.DEBUG


_HINT = "AGENTS_DEBUG=1 or agentsctl run --debug shows the traceback"


def _one_line(exc: AgentsError) -> None:
    text = " ".join(str(exc).split()) or type(exc).__name__
    if already_reported(text):  # the status line above said it: not twice
        print(f"agents: could not start (the reason is above; {_HINT})", file=sys.stderr, flush=True)
    else:
        print(f"agents: error: {text} ({_HINT})", file=sys.stderr, flush=True)


def caused_by_a_bug(exc: BaseException) -> bool:
    """Whether an error that is not the framework's is in ``exc``'s ``__cause__`` chain (user code's bug that
    the framework wrapped, a ``KeyError`` behind "configure failed", say)."""
    seen: set[int] = set()
    cause = exc.__cause__
    while cause is not None and id(cause) not in seen:
        if not isinstance(cause, AgentsError):
            return True
        seen.add(id(cause))
        cause = cause.__cause__
    return False


@contextlib.contextmanager
def short_errors() -> Iterator[None]:
    """Turn an :class:`~agents_core.errors.AgentsError` escaping the block into one line and exit status 1
    (not one caused by a bug: see :func:`caused_by_a_bug`)."""
    try:
        yield
    except AgentsError as exc:
        if debug_requested() or caused_by_a_bug(exc):
            raise
        _one_line(exc)
        raise SystemExit(1) from None


_Hook = Callable[[type[BaseException], BaseException, TracebackType | None], Any]


def _uncaught(previous: _Hook) -> _Hook:
    def hook(kind: type[BaseException], value: BaseException, tb: TracebackType | None) -> None:
        # Only in front of the interpreter's handler: a hook of the user's (a crash reporter) sees every error.
        if (previous is sys.__excepthook__ and isinstance(value, AgentsError) and not caused_by_a_bug(value)
                and already_reported(str(value)) and not debug_requested()):
            _one_line(value)  # the interpreter still exits with status 1
            return
        previous(kind, value, tb)

    hook.agents_one_line = True  # type: ignore[attr-defined]
    return hook


def one_line_if_uncaught() -> None:
    """Make an uncaught framework error whose reason a status line showed print one line, not its traceback
    (installed once, in front of the interpreter's handler; see the module docstring)."""
    if not getattr(sys.excepthook, "agents_one_line", False):
        sys.excepthook = _uncaught(sys.excepthook)
