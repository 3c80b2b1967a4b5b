"""Upstream behaviours of the model components that recipes rely on (issue 26): lenient prompt
templates, tool values on the outputs, ``describe(topic_name, query)``, ``take_picture(topic_name,
save_path)``, a router that forgets the routes of an earlier run."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core import Topic
from agents_core.components import LLM, MLLM, Route, SemanticRouter, Vision
from agents_core.config import LLMConfig, SemanticRouterConfig, VisionConfig
from agents_core.errors import WiringError
from agents_core.messages import ImageMsg

from ..conftest import wait_for
from .scripted_client import ScriptedChatClient, tool_call
from .test_llm import _collect, running
from .test_mllm_and_router import _WordVectorDB
from .vision_recipe import needs_ssd, photo

QUESTION, ANSWER = Topic("question", "String"), Topic("answer", "String")
CAMERA, OTHER_CAMERA = Topic("camera", "Image"), Topic("other_camera", "Image")


def test_a_template_variable_that_has_no_value_renders_empty() -> None:
    client = ScriptedChatClient(["ok"])
    llm = LLM(inputs=[QUESTION, Topic("objects", "Detections")], outputs=[ANSWER], model_client=client,
              config=LLMConfig(), trigger=QUESTION)
    llm.set_topic_prompt(QUESTION, "Seen: {{ objects }}|{{ never_defined }}. Q: {{ question }}")
    with running(llm) as launcher:
        answers = _collect(launcher, ANSWER)
        launcher.transport.create_publisher(QUESTION).publish("where?")
        assert wait_for(lambda: answers == ["ok"])
    assert client.inputs[0]["query"][-1]["content"] == "Seen: |. Q: where?"


def test_a_tool_not_sent_back_gives_its_value_to_the_output() -> None:
    def go_to(x: float, y: float) -> list[float]:
        return [x, y, 0.0]

    client = ScriptedChatClient([tool_call("go_to", {"x": 1.5, "y": -2.0}, "c1")])
    llm = LLM(inputs=[QUESTION], outputs=[ANSWER], model_client=client, trigger=QUESTION)
    llm.register_tool(go_to, {"name": "go_to", "parameters": {"type": "object", "properties": {
        "x": {"type": "number"}, "y": {"type": "number"}}, "required": ["x", "y"]}},
        send_tool_response_to_model=False)
    got_values: list[Any] = []
    # Upstream's recipes turn the tool's value into their output type with a pre-processor.
    llm.add_publisher_preprocessor(ANSWER, lambda value: got_values.append(value) or f"{value[0]},{value[1]}")
    with running(llm) as launcher:
        answers = _collect(launcher, ANSWER)
        launcher.transport.create_publisher(QUESTION).publish("go to the door")
        assert wait_for(lambda: answers == ["1.5,-2.0"])
    assert got_values == [[1.5, -2.0, 0.0]]


def _frame(value: int) -> ImageMsg:
    return ImageMsg(data=np.full((24, 32, 3), value, np.uint8), encoding="rgb8")


def test_describe_takes_upstreams_topic_name_and_query() -> None:
    client = ScriptedChatClient(["a wall"])
    vlm = MLLM(inputs=[QUESTION, CAMERA, OTHER_CAMERA], outputs=[ANSWER], model_client=client, trigger=QUESTION)
    with running(vlm) as launcher:
        launcher.transport.create_publisher(CAMERA).publish(_frame(10))
        launcher.transport.create_publisher(OTHER_CAMERA).publish(_frame(200))
        assert wait_for(lambda: vlm.callbacks["camera"].got_msg and vlm.callbacks["other_camera"].got_msg)
        assert vlm.run_on_worker(lambda: vlm.describe("other_camera", "what is there?")) == "a wall"
        assert vlm.run_on_worker(lambda: vlm.describe(topic_name="camera", query="and here?")) == "a wall"
        assert vlm.run_on_worker(lambda: vlm.describe("what colour?")) == "a wall"  # our form: a question
        with pytest.raises(WiringError, match="not one of its image inputs"):
            vlm.describe(topic_name="nowhere", query="?")
    first, second, third = (c["query"][-1] for c in client.inputs)
    assert first["content"] == "what is there?" and len(first["images"]) == 1
    assert int(first["images"][0][0, 0, 0]) == 200
    assert second["content"] == "and here?" and int(second["images"][0][0, 0, 0]) == 10
    assert third["content"] == "what colour?" and len(third["images"]) == 2


@pytest.mark.local_models
def test_take_picture_takes_upstreams_topic_name_and_save_path(tmp_path: Path) -> None:
    from PIL import Image as PILImage  # noqa: PLC0415  (the local extra's Pillow: only this test needs it)

    objects = Topic("objects", "Detections")
    vision = Vision(inputs=[CAMERA, OTHER_CAMERA], outputs=[objects],
                    config=VisionConfig(enable_local_classifier=True, local_model_path=needs_ssd(),
                                        recordings_dir=str(tmp_path)))
    with running(vision) as launcher:
        launcher.transport.create_publisher(OTHER_CAMERA).publish(
            ImageMsg(data=photo("coffee.png"), encoding="rgb8"))
        picture = vision.run_on_worker(lambda: vision.take_picture("other_camera", str(tmp_path / "pics"),
                                                                   timeout=5.0))
        with pytest.raises(WiringError, match="not one of its cameras"):
            vision.take_picture("nowhere")
    assert picture["detections"][0]["source"] == "other_camera" and "cup" in picture["detections"][0]["labels"]
    saved = Path(picture["path"])
    assert saved.parent == tmp_path / "pics" and saved.suffix == ".png"
    with PILImage.open(saved) as img:
        assert img.size == (photo("coffee.png").shape[1], photo("coffee.png").shape[0])


def test_the_router_forgets_the_routes_of_an_earlier_run() -> None:
    db = _WordVectorDB()
    go, chat = Topic("go", "String"), Topic("talk", "String")
    requests = Topic("requests", "String")
    # An earlier recipe stored a route this router does not have, in the same collection.
    db.rows["llm_query:0"] = ("tell me a joke", {"route_name": "llm_query"})
    real = _ResettingDB(db)
    router = SemanticRouter(inputs=[requests], routes=[Route(routes_to=go, samples=["go to the kitchen"]),
                                                      Route(routes_to=chat, samples=["how are you"])],
                            db_client=real, config=SemanticRouterConfig(router_name="nav", maximum_distance=0.9))
    with running(router) as launcher:
        got = _collect(launcher, chat)
        launcher.transport.create_publisher(requests).publish("tell me a joke, how are you")
        assert wait_for(lambda: got == ["tell me a joke, how are you"])
    assert "llm_query:0" not in db.rows


class _ResettingDB(_WordVectorDB):
    """The word-vector double honouring ``reset_collection`` as Chroma does."""

    def __init__(self, base: _WordVectorDB) -> None:
        super().__init__()
        self.rows = base.rows

    def _add(self, db_input: dict[str, Any]) -> dict[str, Any]:
        if db_input.get("reset_collection"):
            self.rows.clear()
        return super()._add(db_input)
