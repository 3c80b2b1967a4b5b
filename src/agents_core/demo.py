"""A small recipe that shows what flows through a graph (``python -m agents_core.demo``).

A timed camera publishes synthetic frames in which a bright square moves; a detector finds the
square and publishes Detections; a narrator turns detections into sentences; an event fires an
action when the square reaches the right half. Everything that flows is printed. It runs on the
memory transport by default (``--transport`` or ``AGENTS_TRANSPORT`` choose another).
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from typing import Any

import numpy as np

from .actions import Action
from .components import Component
from .events import Event
from .launcher import Launcher
from .messages import DetectionsMsg, Header, ImageMsg
from .supported_types import Detections, Image, String
from .topics import Topic

__all__ = ["build_recipe", "main"]


class SyntheticCamera(Component):
    """Publishes 64x96 frames with a bright 16x16 square moving left to right."""

    def __init__(self, **kwargs: Any) -> None:
        self.allowed_outputs = {"Required": [Image]}
        self.frame = 0
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        pixels = np.zeros((64, 96, 3), np.uint8)
        x = (self.frame * 8) % 80
        pixels[24:40, x:x + 16] = 255
        self.frame += 1
        for pub in self.publishers_dict.values():
            pub.publish(ImageMsg(data=pixels, encoding="rgb8", header=Header(frame_id="camera")))


class BrightSpotDetector(Component):
    """Finds the bright region of each frame (a stand-in for a Vision model)."""

    def __init__(self, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [Image]}
        self.allowed_outputs = {"Required": [Detections]}
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        cb = next(iter(self.trig_callbacks.values()))
        frame: ImageMsg = cb.msg
        ys, xs = np.nonzero(frame.data.max(axis=2) > 128)
        if xs.size:
            box = [[xs.min(), ys.min(), xs.max() + 1, ys.max() + 1]]
            det = DetectionsMsg(boxes=box, labels=["square"], scores=[1.0], header=frame.header)
        else:
            det = DetectionsMsg(header=frame.header)
        for pub in self.publishers_dict.values():
            pub.publish(det)


class Narrator(Component):
    """Describes detections in words."""

    def __init__(self, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [Detections]}
        self.allowed_outputs = {"Required": [String]}
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        det: DetectionsMsg = next(iter(self.trig_callbacks.values())).get_output()
        if not det.labels:
            text = "I see nothing."
        else:
            x1, _, x2, _ = det.boxes[0]
            side = "left" if (x1 + x2) / 2 < 48 else "right"
            text = f"I see a {det.labels[0]} on the {side} at x={int(x1)}."
        for pub in self.publishers_dict.values():
            pub.publish(text)


def build_recipe(rate: float = 5.0) -> tuple[list[Component], dict[Event, Action], dict[str, Topic]]:
    """The demo's components, event wiring and topics."""
    topics = {"image": Topic("camera/image", "Image"), "detections": Topic("detections", "Detections"),
              "description": Topic("description", "String")}
    camera = SyntheticCamera(outputs=[topics["image"]], trigger=rate, component_name="camera")
    detector = BrightSpotDetector(inputs=[topics["image"]], outputs=[topics["detections"]],
                                  trigger=topics["image"], component_name="detector")
    narrator = Narrator(inputs=[topics["detections"]], outputs=[topics["description"]],
                        trigger=topics["detections"], component_name="narrator")
    on_right = Event(name="square_on_right", event_condition=topics["description"].msg.data.contains("right"),
                     on_change=True)
    alert = Action(lambda text: print(f"  [event] square_on_right fired -> action got: {text!r}", flush=True),
                   args=(topics["description"].msg.data,))
    return [camera, detector, narrator], {on_right: alert}, topics


def main(argv: list[str] | None = None) -> int:
    """Run the demo recipe for ``--seconds`` and print what flows."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0, help="how long to run (default 3)")
    parser.add_argument("--transport", default=None, help="memory (default), zenoh or ros2")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")

    components, events_actions, topics = build_recipe()
    launcher = Launcher(transport=args.transport)
    launcher.add_pkg(components=components, events_actions=events_actions)
    print(f"Starting {len(components)} components: {', '.join(c.component_name for c in components)}")
    with launcher:
        t = launcher.transport
        print(f"Transport: {t.name}; all active: {launcher.all_active()}")
        t.create_subscription(topics["image"], lambda m: print(
            f"  camera/image  {m.width}x{m.height} {m.encoding} frame_id={m.header.frame_id}", flush=True))
        t.create_subscription(topics["detections"], lambda d: print(
            f"  detections    {d.labels} boxes={d.boxes.astype(int).tolist()}", flush=True))
        t.create_subscription(topics["description"], lambda s: print(f"  description   {s!r}", flush=True))
        time.sleep(max(0.0, args.seconds))
        if hasattr(t, "statistics"):
            print("Statistics (published / delivered / dropped):")
            for name, s in sorted(t.statistics().items()):
                print(f"  {name:<20} {s.published:>4} / {s.delivered:>4} / {s.dropped:>3}")
    print("Stopped cleanly.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
