"""How component processes start: ``fork`` (from the pre-imported fork server) or ``spawn`` (a fresh interpreter).

Kept apart from :mod:`agents_core.launch.fork_server` so that a recipe checks its choice when it
builds its :class:`~agents_core.launch.launcher.Launcher` without importing the server's
machinery, which only a recipe with ``multiprocessing=True`` needs.
"""

from __future__ import annotations

import os
import sys

__all__ = ["PROCESS_START_ENV", "fork_available", "process_start"]

#: ``fork`` (the default where available) or ``spawn``: how component processes start.
PROCESS_START_ENV = "AGENTS_PROCESS_START"


def fork_available() -> bool:
    """True where the fork server can run: Linux, with fork and descriptor passing."""
    import socket  # noqa: PLC0415 - asked once per launcher, not worth an import for every recipe

    return (sys.platform.startswith("linux") and hasattr(os, "fork") and hasattr(socket, "send_fds")
            and hasattr(socket, "SOCK_SEQPACKET"))


def process_start(option: str | None = None) -> str:
    """``"fork"`` or ``"spawn"``: ``option`` (a launcher's), else :data:`PROCESS_START_ENV`, else fork.

    ``fork`` where :func:`fork_available` says no becomes ``spawn``.
    """
    chosen = (option or os.environ.get(PROCESS_START_ENV, "") or "fork").strip().lower()
    if chosen not in ("fork", "spawn"):
        raise ValueError(f"process start must be 'fork' or 'spawn', got {chosen!r} "
                         f"(from {'the launcher' if option else PROCESS_START_ENV})")
    return "fork" if chosen == "fork" and fork_available() else "spawn"
