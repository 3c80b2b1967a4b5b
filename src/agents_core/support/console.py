"""Short status lines for the person running a recipe, on stderr, without any logging set up.

A recipe started with ``python recipe.py`` should say what it is doing (the transport, the
components coming up, the web UI's address, a download in progress) even when the user has not
configured :mod:`logging`. These lines go to stderr, so a recipe's own stdout stays its own.

They are silenced by ``AGENTS_QUIET=1`` (the test suite sets it), by ``Launcher(quiet=True)``, or by
giving the ``agents_core`` logger (or ``agents_core.support.console``) an explicit level above INFO, as
``logging.getLogger("agents_core").setLevel(logging.WARNING)`` does.

This module imports nothing from the package, so any module may use it.
"""

from __future__ import annotations

import logging
import os
import sys
from typing import TextIO

__all__ = ["QUIET_ENV_VAR", "quiet_requested", "say"]

#: Set to 1 / true / yes to silence the status lines of every recipe in this process.
QUIET_ENV_VAR = "AGENTS_QUIET"

_TRUE = frozenset({"1", "true", "yes", "on"})


def quiet_requested(quiet: bool | None = None) -> bool:
    """Whether status lines are off: ``quiet`` when given, else ``AGENTS_QUIET`` or a logger level above INFO."""
    if quiet is not None:
        return bool(quiet)
    if os.environ.get(QUIET_ENV_VAR, "").strip().lower() in _TRUE:
        return True
    # Only an explicit level counts: by default the root logger says WARNING, which would silence
    # every recipe of a user who never configured logging, the very case these lines are for.
    for name in ("agents_core.support.console", "agents_core"):
        level = logging.getLogger(name).level
        if level != logging.NOTSET:
            return level > logging.INFO
    return False


def say(line: str, *, quiet: bool | None = None, stream: TextIO | None = None) -> None:
    """Write one status line to stderr (or ``stream``) unless status lines are off."""
    if quiet_requested(quiet):
        return
    out = stream if stream is not None else sys.stderr
    try:
        out.write(line + "\n")
        out.flush()
    except (OSError, ValueError):  # a closed or broken stderr must not stop the recipe
        pass
