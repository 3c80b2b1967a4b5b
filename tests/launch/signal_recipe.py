"""A recipe whose one step runs for a minute, for the repeated-signal tests (run as a script).

``python -m tests.launch.signal_recipe <transport> [--stuck-deactivate]`` prints ``STEP STARTED`` once
the long step runs, then waits in ``Launcher.bringup()`` for signals. ``--stuck-deactivate``
also makes the component's deactivate hang, which only a third signal can cut short.
"""

from __future__ import annotations

import sys
import time
from typing import Any

from agents_core import Launcher, Topic
from agents_core.components import Component
from agents_core.config import BaseComponentConfig


class LongStep(Component):
    """Its first step takes a minute (a model call that will not end soon)."""

    def __init__(self, stuck_deactivate: bool, **kwargs: Any) -> None:
        self.stuck_deactivate = stuck_deactivate
        self.ran = False
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        if self.ran:
            return
        self.ran = True
        print("STEP STARTED", flush=True)
        time.sleep(60.0)

    def custom_on_deactivate(self) -> None:
        if self.stuck_deactivate:
            print("DEACTIVATE STUCK", flush=True)
            time.sleep(60.0)


def main(argv: list[str]) -> int:
    transport = argv[0]
    component = LongStep("--stuck-deactivate" in argv, inputs=[], outputs=[Topic("long_out", "String")],
                         trigger=20.0, component_name="long_step",
                         # The first signal would wait this long for the step: a second must cut it short.
                         config=BaseComponentConfig(step_finish_timeout=60.0))
    options: dict[str, Any] = {}
    if transport == "zenoh":
        options = {"listen": [argv[1]], "connect": []}
    launcher = Launcher(transport=transport, transport_options=options)
    launcher.add_pkg(components=[component])
    launcher.bringup()
    print("CLEAN EXIT", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
