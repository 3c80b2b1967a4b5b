"""SIGINT / SIGTERM while a recipe runs: the first stops it cleanly, the second hurries, the third exits.

:func:`stop_signals` installs the handlers for the duration of a ``with`` block (only on the main
thread: Python delivers signals there alone). They are installed before the components start, so
a signal that arrives while they start still ends in a clean stop, and they stay until the block
ends (after the launcher's ``stop()``), so a repeated Ctrl-C never raises KeyboardInterrupt in the
middle of the shutdown.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import threading
from collections.abc import Callable, Iterator
from types import FrameType
from typing import Any

from ..support.console import say

__all__ = ["stop_signals"]

logger = logging.getLogger(__name__)


@contextlib.contextmanager
def stop_signals(request_stop: Callable[[], None], hurry: Callable[[], None], *,
                 quiet: bool | None = None) -> Iterator[None]:
    """Route SIGINT / SIGTERM to ``request_stop`` (first), ``hurry`` (second), exit 128 + signum (third)."""
    previous: dict[signal.Signals, Any] = {}
    received = 0

    def handler(signum: int, frame: FrameType | None) -> None:
        nonlocal received
        received += 1
        if received == 1:
            say("agents: stopping (Ctrl-C again to hurry)", quiet=quiet)
            logger.info("received signal %d, shutting down (again to hurry, a third time to exit at once)", signum)
            request_stop()
        elif received == 2:
            logger.warning("received signal %d again: not waiting for running steps any longer", signum)
            request_stop()
            hurry()
        else:
            os._exit(128 + signum)

    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            previous[sig] = signal.signal(sig, handler)
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
