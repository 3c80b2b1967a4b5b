"""Each component in a process of its own, and a crashed one respawned.

``counter`` counts on ``count`` at 5 Hz; ``flaky`` echoes the counts on ``echo``, and its first
process crashes (``os._exit``) after three steps, as a driver that segfaults would. The launcher
respawns it (``on_process_fail(max_retries=3)``) and the chain goes on. Processes need a
transport that crosses them: Zenoh by default here (ROS 2 works too; memory does not)::

    python examples/multiprocessing_respawn.py                 # until Ctrl-C
    python examples/multiprocessing_respawn.py --once          # stops after the first respawn

The component classes live in this file: each component process imports it (by path, without
running ``main``) to rebuild its component.
"""

from __future__ import annotations

import os
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from agents_core import Launcher, Topic
from agents_core.components import Component

COUNT = Topic("count", "String")
ECHO = Topic("echo", "String")


class Counter(Component):
    """Publishes 1, 2, 3, ... on ``count``."""

    def __init__(self, **kwargs: Any) -> None:
        self.n = 0
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        self.n += 1
        self.publishers_dict["count"].publish(str(self.n))


class Flaky(Component):
    """Echoes what it hears; its first process dies after three steps."""

    def __init__(self, **kwargs: Any) -> None:
        self.steps = 0
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        value = self.trig_callbacks["count"].get_output()
        self.publishers_dict["echo"].publish(f"{value} from pid {os.getpid()}")
        self.steps += 1
        # One marker per launcher (the parent process): only the first life of this process crashes.
        marker = Path(tempfile.gettempdir()) / f"agents-example-flaky-{os.getppid()}"
        if self.steps == 3 and not marker.exists():
            marker.touch()
            os._exit(3)


def main(argv: list[str] | None = None) -> None:
    """Run both components in processes of their own."""
    # Imported here, not at the top: a component process imports this file by path, without
    # this folder on sys.path (and needs only the classes above).
    from example_cli import make_launcher, parser, run  # noqa: PLC0415

    p = parser(__doc__)
    p.set_defaults(transport="zenoh")
    args = p.parse_args(argv)
    launcher = make_launcher(args)
    launcher.add_pkg(components=[
        Counter(inputs=[], outputs=[COUNT], trigger=5.0, component_name="counter"),
        Flaky(inputs=[COUNT], outputs=[ECHO], trigger=COUNT, component_name="flaky"),
    ], multiprocessing=True)
    launcher.on_process_fail(max_retries=3)
    respawned = threading.Event()

    def watch(running: Launcher) -> None:
        running.transport.create_subscription(ECHO, lambda text: print(f"echo: {text}", flush=True))
        while not respawned.is_set():
            supervisor = running.supervisor
            rows = supervisor.describe() if supervisor is not None else []
            restarts = sum(int(row["restarts"]) for row in rows)
            if restarts and running.all_active():
                print(f"respawned: {[(r['name'], r['restarts']) for r in rows if r['restarts']]}", flush=True)
                time.sleep(1.0)  # a few echoes from the new process
                respawned.set()
            time.sleep(0.1)

    try:
        run(launcher, args, on_ready=watch, done=respawned)
    finally:
        (Path(tempfile.gettempdir()) / f"agents-example-flaky-{os.getpid()}").unlink(missing_ok=True)


if __name__ == "__main__":
    main()
