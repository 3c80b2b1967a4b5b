"""A small real recipe for the UI tests: a Shouter (String in, String and Image out) with actions.

``python -m tests.ui.ui_parts --listen tcp/127.0.0.1:PORT`` runs it on Zenoh (``--transport ros2``: on
ROS 2) in its own process
(the attach test's "recipe running elsewhere"); it prints READY once active and stops on SIGTERM.
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np

from agents_core import Topic
from agents_core.actions import component_action
from agents_core.components import Component
from agents_core.ros import Image, String

from ..serve_recipe import serve

WORDS = Topic("words", "String")
SHOUTS = Topic("shouts", "String")
PICTURE = Topic("picture", "Image")
LEVEL = Topic("level", "Float64")


class Shouter(Component):
    """Publishes each input string upper-cased; ``make_picture`` publishes a small red image."""

    def __init__(self, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Required": [String], "Optional": [Image]}
        self.volume = 1
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        value = self.trig_callbacks[WORDS.name].get_output()
        if value is not None:
            self.publishers_dict[SHOUTS.name].publish(value.upper() + "!" * self.volume)

    @component_action(description={"type": "function", "function": {
        "name": "set_volume", "description": "How many exclamation marks to add.",
        "parameters": {"type": "object", "properties": {"volume": {"type": "integer"}}, "required": ["volume"]}}})
    def set_volume(self, volume: int) -> int:
        self.volume = int(volume)
        return self.volume

    @component_action
    def make_picture(self) -> bool:
        pixels = np.zeros((24, 32, 3), np.uint8)
        pixels[:, :, 0] = 255
        if PICTURE.name in self.publishers_dict:
            self.publishers_dict[PICTURE.name].publish(pixels)
        return True

    def not_an_action(self) -> str:
        return "must never be callable from the UI"


def shouter(name: str = "shouter") -> Shouter:
    return Shouter(inputs=[WORDS], outputs=[SHOUTS, PICTURE], trigger=WORDS, component_name=name)


def main() -> int:
    return serve(lambda: [shouter()])


if __name__ == "__main__":
    sys.exit(main())
