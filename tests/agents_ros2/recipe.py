"""A recipe run in its own process by the ROS 2 interop test.

``python -m tests.agents_ros2.recipe`` brings up two components on ``Launcher(transport="ros2")`` and
runs until SIGTERM / SIGINT:

- ``relay`` (lifecycle node ``/relay``): ``/chat_in`` (std_msgs/String) -> ``/chat_out``
  (std_msgs/String), the text reversed, fired by each input;
- ``detector`` (lifecycle node ``/detector``): ``/camera`` (sensor_msgs/Image) -> ``/objects``
  (agents_interfaces/Detections2D): one box around the image's brightest pixel, labelled with
  the image's size, carrying the image's header.

Both serve ``input_counters`` through ``<name>/execute_method`` (agents_interfaces/srv/JsonCall),
so a plain ROS 2 node can read the subscription counters, decode errors included.
"""

from __future__ import annotations

import logging
import sys
from typing import Any

import numpy as np

from agents_core import Component, Launcher, Topic, component_action
from agents_core.messages import DetectionsMsg
from agents_core.supported_types import Detections, Image, String


class _Counted(Component):
    @component_action
    def input_counters(self) -> dict[str, int]:
        """This component's subscription counters, summed over its inputs."""
        names = ("delivered", "dropped", "callback_errors", "decode_errors")
        totals = dict.fromkeys(names, 0)
        for stats in self.input_statistics().values():
            for name in names:
                totals[name] += int(getattr(stats, name))
        return totals


class ReverseRelay(_Counted):
    """Publishes each input string reversed."""

    def __init__(self, source: Topic, sink: Topic) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Required": [String]}
        super().__init__(inputs=[source], outputs=[sink], trigger=source, component_name="relay")

    def _execution_step(self, **kwargs: Any) -> None:
        text = self.trig_callbacks[self.inputs[0].name].get_output()
        self.publishers_dict[self.outputs[0].name].publish(text[::-1])


class BrightestPixel(_Counted):
    """Detects 'the brightest pixel' of each image: a 1x1 box around it."""

    def __init__(self, camera: Topic, objects: Topic) -> None:
        self.allowed_inputs = {"Required": [Image]}
        self.allowed_outputs = {"Required": [Detections]}
        super().__init__(inputs=[camera], outputs=[objects], trigger=camera, component_name="detector")

    def _execution_step(self, **kwargs: Any) -> None:
        image = self.trig_callbacks[self.inputs[0].name].msg
        gray = image.data.astype(np.float32).sum(axis=2)
        row, col = np.unravel_index(int(np.argmax(gray)), gray.shape)
        self.publishers_dict[self.outputs[0].name].publish(DetectionsMsg(
            boxes=[[col, row, col + 1, row + 1]], labels=[f"brightest_{image.width}x{image.height}"],
            scores=[1.0], image=image, header=image.header))


def main() -> None:
    logging.basicConfig(level=logging.INFO, stream=sys.stderr, format="%(levelname)s %(name)s: %(message)s")
    relay = ReverseRelay(Topic("chat_in", "String"), Topic("chat_out", "String"))
    detector = BrightestPixel(Topic("camera", "Image"), Topic("objects", "Detections"))
    launcher = Launcher(transport="ros2")
    launcher.add_pkg(components=[relay, detector])
    print("recipe: starting", file=sys.stderr, flush=True)
    launcher.bringup()
    print("recipe: stopped cleanly", file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
