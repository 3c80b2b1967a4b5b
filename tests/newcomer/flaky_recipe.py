"""A component whose step fails at every step, in its own process on Zenoh: ``python flaky_recipe.py``.

Prints ``READY`` once active; runs ``--seconds`` (default 6) and stops.
"""

from __future__ import annotations

import sys
import time
from typing import Any

from agents_core import Launcher
from agents_core.components import Component


class Flaky(Component):
    """Fails at every step."""

    def _execution_step(self, **kwargs: Any) -> None:
        raise RuntimeError("the sensor is unplugged")


if __name__ == "__main__":
    launcher = Launcher(transport="zenoh")
    launcher.add_pkg(components=[Flaky(inputs=[], outputs=[], trigger=20.0, component_name="flaky")],
                     multiprocessing=True)
    with launcher:
        print("READY", flush=True)
        time.sleep(float(sys.argv[1]) if len(sys.argv) > 1 else 6.0)
