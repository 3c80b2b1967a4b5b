"""A recipe on ``Launcher(transport="rmw_zenoh")`` for the CLI test: ``relay`` upper-cases ``relay_in`` into
``relay_out``. Reaches its router through rmw_zenoh's ``ZENOH_CONFIG_OVERRIDE``; prints READY once active."""

from __future__ import annotations

import threading
import time
from typing import Any

from agents_core import Component, Launcher, Topic, component_action
from agents_core.supported_types import String


class Relay(Component):
    """Publishes every input string upper-cased."""

    def __init__(self, inp: Topic, out: Topic, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Required": [String]}
        super().__init__(inputs=[inp], outputs=[out], trigger=inp, component_name="relay", **kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        text = self.trig_callbacks[self.inputs[0].name].get_output()
        self.publishers_dict[self.outputs[0].name].publish(text.upper())

    @component_action
    def shout(self, word: str) -> str:
        """The word upper-cased (an action for ``agentsctl call``)."""
        return word.upper() + "!"


def _announce(launcher: Launcher) -> None:
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if launcher.components and all(c.lifecycle_state.value == "active" for c in launcher.components):
            print("READY", flush=True)
            return
        time.sleep(0.1)


if __name__ == "__main__":
    launcher = Launcher(transport="rmw_zenoh")
    launcher.add_pkg(components=[Relay(Topic("relay_in", "String"), Topic("relay_out", "String"))])
    threading.Thread(target=_announce, args=(launcher,), daemon=True).start()
    launcher.bringup()
