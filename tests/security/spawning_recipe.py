"""A recipe whose one component starts processes: ``python spawning_recipe.py --port P --markers DIR``.

Its ``Spawner`` runs in a process of its own (``multiprocessing=True``, Zenoh on loopback). On
activate it starts a ``sleep`` child directly and another one through ``sh -c 'sleep ... &'``
(orphaned at once: the double fork a daemon does), and writes ``pids.<component pid>`` (the two
sleeps' pids, one a line) in the marker folder. ``--stubborn``: the direct child ignores SIGTERM
(``trap '' TERM``), and so does a child of its own. ``--bystander``: a second component, from
:mod:`bystander_component` (whose import starts a helper process, in the fork server too).
"""

from __future__ import annotations

import argparse
import logging
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from agents_core import Component, Topic
from agents_core.launch.launcher import Launcher
from agents_core.supported_types import String


class Spawner(Component):
    """Starts two long sleeps when activated; see the module docstring."""

    def __init__(self, component_name: str, markers: str, stubborn: bool = False, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        source = Topic("spawn/in", "String")
        super().__init__(inputs=[source], trigger=source, component_name=component_name, **kwargs)
        self.markers = markers
        self.stubborn = stubborn

    def custom_on_activate(self) -> None:
        stubborn = "trap '' TERM; sleep 300 & exec sleep 300"  # and so is its child, which it leaves behind
        direct = subprocess.Popen(["sh", "-c", stubborn] if self.stubborn else ["sleep", "300"])
        marker = Path(self.markers, f"orphan.{os.getpid()}")
        subprocess.run(["sh", "-c", f"sleep 300 & echo $! > {marker}"], check=True)
        deadline = time.monotonic() + 5
        while not marker.exists() or not marker.read_text().strip():
            if time.monotonic() > deadline:
                raise RuntimeError("the orphan's pid did not appear")
            time.sleep(0.01)
        orphan = int(marker.read_text())
        Path(self.markers, f"pids.{os.getpid()}").write_text(f"{direct.pid}\n{orphan}\n")

    def _execution_step(self, **kwargs: Any) -> None:
        pass


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--markers", required=True)
    parser.add_argument("--stubborn", action="store_true")
    parser.add_argument("--bystander", action="store_true")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, stream=sys.stderr)
    launcher = Launcher(transport="zenoh", transport_options={
        "mode": "peer", "listen": [f"tcp/127.0.0.1:{args.port}"], "connect": [], "multicast_scouting": False})
    components: list[Component] = [Spawner("spawner", args.markers, stubborn=args.stubborn)]
    if args.bystander:
        from bystander_component import Bystander  # noqa: PLC0415  # its import starts a helper process

        components.append(Bystander("bystander", args.markers))
    launcher.add_pkg(components=components, multiprocessing=True)
    launcher.bringup()


if __name__ == "__main__":
    main()
