"""``agentsctl top``'s test recipe: ``python -m tests.telemetry.top_recipe --transport zenoh --listen EP``.

Two components, a process each: ``ticker`` publishes a count on ``top/ticks`` at 20 Hz (a timed
component), ``echo`` republishes each tick on ``top/echo`` after a short sleep, so both have steps,
a step rate and step times that move.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

from agents_core import Component, Launcher, Topic
from agents_core.supported_types import String
from tests.components.recipe_main import serve, transport_options

TICKS = Topic(name="top/ticks", msg_type="String")
ECHO = Topic(name="top/echo", msg_type="String")


class Ticker(Component):
    """Publishes 1, 2, 3, ... at ``rate`` Hz."""

    def __init__(self, rate: float = 20.0, component_name: str = "ticker", **kwargs: Any) -> None:
        self.allowed_outputs = {"Required": [String]}
        super().__init__(outputs=[TICKS], trigger=rate, component_name=component_name, **kwargs)
        self.count = 0

    def _execution_step(self, **kwargs: Any) -> None:
        self.count += 1
        self.publishers_dict[TICKS.name].publish(str(self.count))


class Echo(Component):
    """Republishes each tick after ``delay`` seconds."""

    def __init__(self, delay: float = 0.002, component_name: str = "echo", **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Required": [String]}
        super().__init__(inputs=[TICKS], outputs=[ECHO], trigger=TICKS, component_name=component_name, **kwargs)
        self.delay = delay

    def _execution_step(self, **kwargs: Any) -> None:
        time.sleep(self.delay)
        self.publishers_dict[ECHO.name].publish(self.trig_callbacks[TICKS.name].get_output())


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--transport", required=True, choices=["zenoh"])
    parser.add_argument("--listen", required=True)
    args = parser.parse_args(argv)
    launcher = Launcher(transport=args.transport, transport_options=transport_options(args.transport, args.listen))
    launcher.add_pkg(components=[Ticker(), Echo()], multiprocessing=True)
    serve(launcher)


if __name__ == "__main__":
    main()
