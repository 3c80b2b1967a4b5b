"""A recipe with a held call for the approval panel's tests: the MCP tests' Arm, its ``launch`` needing a yes."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from agents_core import Launcher
from agents_core.errors import AgentsError

from ..mcp.mcp_parts import COMMANDS, MOTION, arm


@contextmanager
def arm_with_ui() -> Iterator[tuple[Launcher, Any]]:
    """A running recipe (memory) with the Arm and its UI on a free port."""
    component = arm()
    launcher = Launcher("memory")
    launcher.add_pkg(components=[component])
    launcher.enable_ui(inputs=[COMMANDS], outputs=[MOTION], port=0)
    with launcher:
        yield launcher, component


class HeldCall:
    """``arm.launch(target)`` called on a thread (as the CLI would: ``execute_method``); held until decided."""

    def __init__(self, launcher: Launcher, target: str) -> None:
        self.result: Any = None
        self.error: str | None = None
        request = {"method": "launch", "kwargs": {"target": target}, "timeout": 10.0, "caller": "cli"}

        def run() -> None:
            try:
                self.result = launcher.transport.request("arm/execute_method", request, timeout=11.0)
            except AgentsError as exc:
                self.error = str(exc)

        self._thread = threading.Thread(target=run, name=f"held-{target}", daemon=True)
        self._thread.start()

    def join(self, timeout: float = 15.0) -> None:
        self._thread.join(timeout)
        assert not self._thread.is_alive(), "the held call did not end"
