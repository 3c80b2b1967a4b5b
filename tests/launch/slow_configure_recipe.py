"""A recipe whose component is slow to configure: ``python slow_configure_recipe.py --configure-s S --markers DIR``.

Its one ``SlowStart`` component runs in a process of its own (``multiprocessing=True``). Its
``custom_on_configure`` writes ``configure.<pid>`` in the marker folder, then sleeps ``S``
seconds (a negative ``S``: an hour, a configure that never returns); its ``custom_on_activate``
writes ``active.<pid>``; with ``fail=True`` the configure raises after its sleep, with ``stuck_deactivate=True`` the
deactivate (which writes ``deactivate.<pid>``) never returns. The tests kill
the launcher or the child during the configure and look at the markers and the pids.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import time
from pathlib import Path
from typing import Any

from agents_core import Component, Topic
from agents_core.launch.launcher import Launcher
from agents_core.supported_types import String


class SlowStart(Component):
    """Configures for ``configure_s`` seconds (forever when negative); marks configure and activate."""

    def __init__(self, component_name: str, configure_s: float, markers: str, fail: bool = False,
                 stuck_deactivate: bool = False, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Required": [String]}
        source = Topic("slow/in", "String")
        super().__init__(inputs=[source], outputs=[Topic("slow/out", "String")], trigger=source,
                         component_name=component_name, **kwargs)
        self.configure_s = configure_s
        self.markers = markers
        self.fail = fail
        self.stuck_deactivate = stuck_deactivate

    def custom_on_configure(self) -> None:
        Path(self.markers, f"configure.{os.getpid()}").write_text(str(time.time()))
        time.sleep(3600.0 if self.configure_s < 0 else self.configure_s)
        if self.fail:
            raise RuntimeError("configure failed on purpose")

    def custom_on_activate(self) -> None:
        Path(self.markers, f"active.{os.getpid()}").write_text(str(time.time()))

    def custom_on_deactivate(self) -> None:
        Path(self.markers, f"deactivate.{os.getpid()}").write_text(str(time.time()))
        if self.stuck_deactivate:
            time.sleep(3600.0)

    def _execution_step(self, **kwargs: Any) -> None:
        text = self.trig_callbacks["slow/in"].get_output()
        self.publishers_dict["slow/out"].publish(text)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--transport", default="zenoh")
    parser.add_argument("--port", type=int, default=0)
    parser.add_argument("--configure-s", type=float, required=True)
    parser.add_argument("--markers", required=True)
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, stream=sys.stderr)
    options: dict[str, Any] | None = None
    if args.transport == "zenoh":
        options = {"mode": "peer", "listen": [f"tcp/127.0.0.1:{args.port}"], "connect": [],
                   "multicast_scouting": False}
    launcher = Launcher(transport=args.transport, transport_options=options)
    launcher.add_pkg(components=[SlowStart("slow", args.configure_s, args.markers)], multiprocessing=True)
    launcher.bringup()


if __name__ == "__main__":
    main()
