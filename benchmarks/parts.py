"""The components the benchmarks run: a relay (String and Image) and a chain of five for start-up."""

from __future__ import annotations

from typing import Any

from agents_core import Component, Topic
from agents_core.supported_types import Image, String

from .common import TOPICS


class EchoRelay(Component):
    """Publishes every value it receives, unchanged, on the matching output.

    Inputs ``bench/str_in`` (String) and ``bench/img_in`` (Image), either of which fires a step;
    outputs ``bench/str_out`` and ``bench/img_out``. The step does no work of its own, so what a
    hop through it costs is the framework: subscription, decoding, the trigger, the serial worker,
    validation, encoding and publishing.
    """

    def __init__(self, component_name: str = "relay", **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String, Image]}
        self.allowed_outputs = {"Required": [String, Image]}
        str_in, str_out = TOPICS["string64"]
        img_in, img_out = TOPICS["image640x480"]
        inputs = [Topic(str_in, "String"), Topic(img_in, "Image")]
        outputs = [Topic(str_out, "String"), Topic(img_out, "Image")]
        self._route = {str_in: str_out, img_in: img_out}
        super().__init__(inputs=inputs, outputs=outputs, trigger=inputs, component_name=component_name, **kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        topic = kwargs["topic"]
        value = self.trig_callbacks[topic.name].msg  # the message form: str, or ImageMsg with its header
        self.publishers_dict[self._route[topic.name]].publish(value)


class Stage(Component):
    """One String stage of a pipeline (``inp`` -> ``out``), for the start-up benchmark."""

    def __init__(self, inp: str, out: str, component_name: str) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Required": [String]}
        source = Topic(inp, "String")
        super().__init__(inputs=[source], outputs=[Topic(out, "String")], trigger=source,
                         component_name=component_name)

    def _execution_step(self, **kwargs: Any) -> None:
        text = self.trig_callbacks[self.inputs[0].name].get_output()
        self.publishers_dict[self.outputs[0].name].publish(text)


def five_stage_recipe(prefix: str = "startup") -> list[Component]:
    """Five components in a chain: ``<prefix>/t0`` -> stage0 -> ``t1`` -> ... -> stage4 -> ``t5``."""
    return [Stage(f"{prefix}/t{i}", f"{prefix}/t{i + 1}", f"stage{i}") for i in range(5)]


class Merge(Component):
    """Three String inputs (any of them triggers), one output: the thread-count figure's component."""

    def __init__(self, prefix: str) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Required": [String]}
        sources = [Topic(f"{prefix}/in{i}", "String") for i in range(3)]
        super().__init__(inputs=sources, outputs=[Topic(f"{prefix}/out", "String")], trigger=sources,
                         component_name="merge")

    def _execution_step(self, **kwargs: Any) -> None:
        topic = kwargs["topic"]
        self.publishers_dict[self.outputs[0].name].publish(self.trig_callbacks[topic.name].get_output())
