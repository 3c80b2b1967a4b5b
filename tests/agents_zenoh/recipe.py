"""A recipe run in its own process by the Zenoh integration tests.

``python -m tests.agents_zenoh.recipe --listen tcp/127.0.0.1:PORT --namespace NS`` brings up two
components on ``Launcher(transport="zenoh")`` and runs until SIGTERM / SIGINT (or is killed):

- ``relay``: ``relay_in`` (String) -> ``relay_out`` (String), the text upper-cased;
- ``vision``: ``camera`` (Image) -> ``image_mean`` (String, ``"mean=<value>"``) and
  ``detections`` (Detections: one box over the whole image, with the image attached).

Both expose ``input_statistics`` through their ``execute_method`` service, so a plain Zenoh
client can read the subscription counters (decode errors included) with a query.
"""

from __future__ import annotations

import argparse
import logging
import sys
from typing import Any

from agents_core import Component, Launcher, Topic, component_action
from agents_core.messages import DetectionsMsg
from agents_core.supported_types import Detections, Image, String


class _CountingComponent(Component):
    @component_action
    def input_statistics(self) -> dict[str, int]:
        """Subscription counters of this component's inputs, summed."""
        totals = {"delivered": 0, "dropped": 0, "callback_errors": 0, "decode_errors": 0}
        for stats in super().input_statistics().values():
            for name in totals:
                totals[name] += getattr(stats, name, 0)
        return totals


class Relay(_CountingComponent):
    """Publishes every input string upper-cased."""

    def __init__(self, inp: Topic, out: Topic, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Required": [String]}
        super().__init__(inputs=[inp], outputs=[out], trigger=inp, component_name="relay", **kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        text = self.trig_callbacks[self.inputs[0].name].get_output()
        self.publishers_dict[self.outputs[0].name].publish(text.upper())


class ImageStats(_CountingComponent):
    """Publishes each image's mean pixel value, and a detection box over the whole image."""

    def __init__(self, camera: Topic, mean: Topic, detections: Topic, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [Image]}
        self.allowed_outputs = {"Required": [String], "Optional": [Detections]}
        super().__init__(inputs=[camera], outputs=[mean, detections], trigger=camera,
                         component_name="vision", **kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        image = self.trig_callbacks[self.inputs[0].name].msg
        mean = float(image.data.mean())
        self.publishers_dict["image_mean"].publish(f"mean={mean:.3f}")
        self.publishers_dict["detections"].publish(DetectionsMsg(
            boxes=[[0, 0, image.width, image.height]], labels=[f"mean={mean:.1f}"], scores=[1.0],
            image=image, header=image.header))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--listen", required=True, help="e.g. tcp/127.0.0.1:7500")
    parser.add_argument("--namespace", default="")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, stream=sys.stderr,
                        format="%(levelname)s %(name)s: %(message)s")
    relay = Relay(Topic("relay_in", "String"), Topic("relay_out", "String"))
    vision = ImageStats(Topic("camera", "Image"), Topic("image_mean", "String"),
                        Topic("detections", "Detections"))
    launcher = Launcher(transport="zenoh", transport_options={
        "mode": "peer", "listen": [args.listen], "connect": [], "namespace": args.namespace,
        "multicast_scouting": False,
    })
    launcher.add_pkg(components=[relay, vision])
    launcher.bringup()


if __name__ == "__main__":
    main()
