"""``MLLM`` (alias ``VLM``): a component that answers questions about images.

It is an :class:`~agents_core.components.llm.LLM` that also reads Image inputs and sends the
latest frame of each with the question. With ``config.task`` set to a structured task the model
is asked for coordinates as JSON, and the answer is parsed into a typed output:

| task | the model is asked for | published as |
|---|---|---|
| general | a text answer | String / StreamingString |
| grounding | boxes of the objects named in the question | Detections |
| affordance | boxes of where to act on the named object | Detections |
| pointing | points on the named objects | PointsOfInterest |
| trajectory | an ordered path of points | PointsOfInterest |

Images are never kept in the chat history.
"""

from __future__ import annotations

import json
import re
import time
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from ..actions import component_action
from ..clients.db_base import DBClient
from ..clients.model_base import ModelClient
from ..errors import AlgorithmFailure, WiringError
from ..messages import DetectionsMsg, ImageMsg, PointsOfInterestMsg
from ..supported_types import Detections, Image, PointsOfInterest, StreamingString, String, SupportedType
from ..topics import Topic
from .component_base import TriggerType
from .llm import LLM
from .mllm_config import MLLMConfig

__all__ = ["MLLM", "VLM"]

_TASK_INSTRUCTIONS = {
    "grounding": 'Find: {query}\nReply only with JSON: [{{"label": "<name>", "bbox": [x1, y1, x2, y2]}}, ...] in '
                 "pixel coordinates of the {width}x{height} image.",
    "affordance": 'Where should a robot hand act to: {query}\nReply only with JSON: [{{"label": "<part>", '
                  '"bbox": [x1, y1, x2, y2]}}, ...] in pixel coordinates of the {width}x{height} image.',
    "pointing": 'Point at: {query}\nReply only with JSON: [{{"label": "<name>", "point": [x, y]}}, ...] in pixel '
                "coordinates of the {width}x{height} image.",
    "trajectory": "Plan a path for: {query}\nReply only with JSON: [[x, y], ...], the ordered waypoints in pixel "
                  "coordinates of the {width}x{height} image.",
}

_TASK_OUTPUT: dict[str, type[SupportedType]] = {
    "grounding": Detections, "affordance": Detections, "pointing": PointsOfInterest, "trajectory": PointsOfInterest,
}


def _first_json(text: str) -> Any:
    """The first JSON array or object in ``text`` (models like to wrap it in prose or code fences)."""
    decoder = json.JSONDecoder()
    for match in re.finditer(r"[\[{]", text):
        try:
            value, _ = decoder.raw_decode(text, match.start())
        except json.JSONDecodeError:
            continue
        return value
    raise ValueError("no JSON array or object in the answer")


class MLLM(LLM):
    """Answers questions about images with a multimodal model (a client, or the built-in local VLM).

    :param inputs: String topics and Image topics (both required), optional Detections topics.
    :param outputs: String / StreamingString for ``task="general"``; Detections or
        PointsOfInterest for the structured tasks (see the module docs).
    Other parameters as :class:`~agents_core.components.llm.LLM`; ``config`` is an
    :class:`~agents_core.config.MLLMConfig`.
    """

    config_class = MLLMConfig

    def __init__(
        self,
        inputs: Sequence[Topic] | None = None,
        outputs: Sequence[Topic] | None = None,
        model_client: ModelClient | None = None,
        config: MLLMConfig | None = None,
        db_client: DBClient | None = None,
        trigger: TriggerType = 1.0,
        component_name: str = "mllm",
        **kwargs: Any,
    ) -> None:
        self.allowed_inputs = {"Required": [String, Image], "Optional": [Detections]}
        # Any output type, as LLM: other types need a publisher pre-processor (checked at configure).
        self.allowed_outputs = None
        self.handled_outputs = [String, StreamingString, Detections, PointsOfInterest]
        super().__init__(inputs=inputs, outputs=outputs, model_client=model_client, config=config,
                         db_client=db_client, trigger=trigger, component_name=component_name, **kwargs)
        self.config: MLLMConfig
        wanted = _TASK_OUTPUT.get(self.config.task)
        if wanted is not None and not any(issubclass(t.msg_type, wanted) for t in self.outputs):
            raise WiringError(f"component {self.component_name!r}: task {self.config.task!r} publishes "
                              f"{wanted.type_name()}, but no output topic has that type")

    def _latest_frames(self, source: str | None = None) -> list[ImageMsg]:
        frames: list[ImageMsg] = []
        for name, cb in {**self.callbacks, **self.trig_callbacks}.items():
            if issubclass(self._topic(name).msg_type, Image) and cb.msg is not None and source in (None, name):
                frames.append(cb.msg)
        return frames

    def _answer(self, query: str, source: str | None = None, timeout: float = 0.0) -> str | None:
        """Ask ``query`` about the latest frames (of ``source`` only when given, waiting up to ``timeout``
        seconds for one); a structured task publishes its typed output."""
        deadline = time.monotonic() + timeout
        frames = self._latest_frames(source)
        while not frames and time.monotonic() < deadline:
            time.sleep(0.02)
            frames = self._latest_frames(source)
        if not frames:
            self._logger.warning("no image has arrived yet: question %r not asked", query[:80])
            return None
        images = [f.to_rgb() for f in frames]
        task = self.config.task
        prompt = query
        if task in _TASK_INSTRUCTIONS:
            height, width = images[0].shape[:2]
            prompt = _TASK_INSTRUCTIONS[task].format(query=query, width=width, height=height)
        inference_input = self._create_input(prompt, images=images)
        if inference_input is None:
            return None
        if task != "general":
            # Structured answers are parsed whole: no streaming, no tools.
            inference_input["stream"] = False
            inference_input.pop("tools", None)
            result = self._call_inference(inference_input)
            output = result["output"]
            text = output if isinstance(output, str) else "".join(output)
            self._publish_structured(text, frames[0])
            answer: str | None = text
        else:
            answer = self._converse(inference_input)
        if answer is not None and self.config.chat_history:
            self._remember(query, answer)
        return answer

    def _publish_structured(self, text: str, frame: ImageMsg) -> None:
        task = self.config.task
        try:
            items = _first_json(text)
            if task in ("grounding", "affordance"):
                msg: Any = self._to_detections(items, frame)
            else:
                msg = self._to_points(items, frame)
        except (ValueError, TypeError, KeyError) as exc:
            raise AlgorithmFailure(f"component {self.component_name!r}: task {task!r}: cannot read the model's "
                                   f"answer {text[:200]!r}: {exc}") from exc
        typed = Detections if isinstance(msg, DetectionsMsg) else PointsOfInterest
        for pub in self.publishers_dict.values():
            if issubclass(pub.topic.msg_type, typed):
                pub.publish(msg)
            elif (issubclass(pub.topic.msg_type, String) or pub.has_preprocessors) \
                    and not issubclass(pub.topic.msg_type, StreamingString):
                pub.publish(text)

    @staticmethod
    def _items(value: Any) -> list[Any]:
        return value if isinstance(value, list) else [value]

    def _to_detections(self, value: Any, frame: ImageMsg) -> DetectionsMsg:
        items = [i for i in self._items(value) if isinstance(i, dict)]
        boxes = np.array([[float(c) for c in i["bbox"]] for i in items], np.float32).reshape(-1, 4)
        labels = [str(i.get("label", "")) for i in items]
        return DetectionsMsg(boxes=boxes, labels=labels, scores=np.ones(len(labels), np.float32),
                             image=frame, header=frame.header)

    def _to_points(self, value: Any, frame: ImageMsg) -> PointsOfInterestMsg:
        points: list[Iterable[Any]] = []
        for item in self._items(value):
            point = item["point"] if isinstance(item, dict) else item
            points.append(point)
        array = np.array([[float(c) for c in p] for p in points], np.float32).reshape(-1, 2)
        return PointsOfInterestMsg(points=array, image=frame, header=frame.header)

    @component_action(description={
        "description": "Describe what the robot's camera sees, or answer a question about it.",
        "parameters": {"type": "object",
                       "properties": {"query": {"type": "string", "description": "what to ask about the image"},
                                      "topic_name": {"type": "string", "description": "the camera topic (optional)"}},
                       "required": []},
    })
    def describe(self, topic_name: str | None = None, query: str | None = None, timeout: float = 0.5, *,
                 question: str | None = None) -> str:
        """Ask about the latest image now; the answer is published and returned.

        Upstream's form ``describe(topic_name, query)`` looks at that image input only (waiting up
        to ``timeout`` seconds for a frame); ``describe(question)`` and ``describe(question=...)``
        ask about every image input's latest frame.
        """
        images = {t.name for t in self.inputs if issubclass(t.msg_type, Image)}
        if topic_name is not None and topic_name not in images and query is None and question is None:
            topic_name, question = None, topic_name  # describe("what is on the table?"): a question, not a topic
        if topic_name is not None and topic_name not in images:
            raise WiringError(f"component {self.component_name!r}: {topic_name!r} is not one of its image inputs "
                              f"{sorted(images)}")
        text = query or question or "Describe what you see in one sentence."
        return self._answer(text, topic_name, timeout if topic_name is not None else 0.0) or ""

    def _deploy_local_model(self) -> None:
        from ..engines.local_llm import LocalVLM  # noqa: PLC0415  (llama-cpp-python is optional)

        self.local_model = LocalVLM(model_path=self.config.local_model_path, device=self.config.device_local_model,
                                    ncpu=self.config.ncpu_local_model, mmproj_path=self.config.local_mmproj_path)

    def _warmup(self, *args: Any, **kwargs: Any) -> None:
        blank = np.zeros((32, 32, 3), np.uint8)
        result = self._call_inference({"query": [{"role": "user", "content": "Hello", "images": [blank]}],
                                       "max_new_tokens": 4, "temperature": 0.0, "stream": False})
        output = result["output"]
        if not isinstance(output, str):
            for _ in output:
                pass


#: The upstream name of the same component.
VLM = MLLM
