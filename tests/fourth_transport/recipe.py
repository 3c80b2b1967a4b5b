"""The CLI test recipe's talker and listener, each in a process of its own, on whatever ``AGENTS_TRANSPORT`` names.

``agentsctl run tests/fourth_transport/recipe.py --transport zenloop`` (Zenoh endpoints from
``AGENTS_ZENOH_LISTEN``). Prints ``PIDS <json>`` (component name -> process id) once every
component is active, then runs until SIGINT.
"""

from __future__ import annotations

import json
import threading
import time

from agents_core import Launcher
from tests.cli.cli_recipe import build


def _announce(launcher: Launcher) -> None:
    deadline = time.monotonic() + 90.0
    while time.monotonic() < deadline:
        supervisor = launcher.supervisor
        if supervisor is not None and supervisor.all_active():
            print("PIDS " + json.dumps({str(r["name"]): r["pid"] for r in supervisor.describe()}), flush=True)
            return
        time.sleep(0.2)


if __name__ == "__main__":
    launcher = Launcher()
    launcher.add_pkg(components=build("all"), multiprocessing=True)
    threading.Thread(target=_announce, args=(launcher,), daemon=True).start()
    launcher.bringup()
