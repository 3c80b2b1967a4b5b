"""MLLM (VLM) and SemanticRouter with test doubles: images, structured tasks, both routing modes."""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np
import pytest

from agents_core import Topic
from agents_core.actions import Action
from agents_core.clients import ChromaClient, DBClient, GenericHTTPClient
from agents_core.components import MLLM, VLM, Route, SemanticRouter
from agents_core.config import MLLMConfig, SemanticRouterConfig, VLMConfig
from agents_core.errors import ConfigError, WiringError
from agents_core.messages import DetectionsMsg, ImageMsg
from agents_core.models import GenericLLM
from agents_core.status import HealthStatus
from agents_core.testing.helpers import free_tcp_port
from agents_core.vectordbs import DB, ChromaDB

from ..conftest import wait_for
from .scripted_client import ScriptedChatClient, tool_call
from .test_llm import _collect, running

QUESTION, CAMERA = Topic("question", "String"), Topic("camera", "Image")
ANSWER, OBJECTS, POINTS = Topic("answer", "String"), Topic("objects", "Detections"), Topic("points", "PointsOfInterest")


def _frame(value: int = 40) -> ImageMsg:
    return ImageMsg(data=np.full((48, 64, 3), value, np.uint8), encoding="rgb8")


def test_vlm_is_the_mllm() -> None:
    assert VLM is MLLM and VLMConfig is MLLMConfig


def test_mllm_sends_the_latest_image_and_keeps_it_out_of_history() -> None:
    client = ScriptedChatClient(["a grey wall", "still grey"])
    vlm = MLLM(inputs=[QUESTION, CAMERA], outputs=[ANSWER], model_client=client,
               config=MLLMConfig(chat_history=True), trigger=QUESTION)
    with running(vlm) as launcher:
        answers = _collect(launcher, ANSWER)
        t = launcher.transport
        t.create_publisher(CAMERA).publish(_frame(40))
        assert wait_for(lambda: vlm.callbacks["camera"].got_msg)
        t.create_publisher(QUESTION).publish("what do you see?")
        assert wait_for(lambda: len(answers) == 1)
        t.create_publisher(CAMERA).publish(_frame(90))
        assert wait_for(lambda: int(vlm.callbacks["camera"].msg.data[0, 0, 0]) == 90)
        t.create_publisher(QUESTION).publish("and now?")
        assert wait_for(lambda: len(answers) == 2)
    first, second = client.inputs[0]["query"], client.inputs[1]["query"]
    assert first[-1]["content"] == "what do you see?"
    assert first[-1]["images"][0].shape == (48, 64, 3) and int(first[-1]["images"][0][0, 0, 0]) == 40
    assert int(second[-1]["images"][0][0, 0, 0]) == 90, "the newest frame is sent"
    assert [m.get("images") for m in second[:-1]] == [None, None], "history holds text only"
    assert all("images" not in m for m in vlm.messages)


def test_grounding_task_publishes_detections() -> None:
    reply = 'Sure! ```json\n[{"label": "cup", "bbox": [10, 12, 30, 40]}, {"label": "apple", "bbox": [1, 2, 3, 4]}]```'
    client = ScriptedChatClient([reply])
    vlm = MLLM(inputs=[QUESTION, CAMERA], outputs=[OBJECTS, ANSWER], model_client=client,
               config=MLLMConfig(task="grounding"), trigger=QUESTION)
    with running(vlm) as launcher:
        found, text = _collect(launcher, OBJECTS), _collect(launcher, ANSWER)
        launcher.transport.create_publisher(CAMERA).publish(_frame())
        assert wait_for(lambda: vlm.callbacks["camera"].got_msg)
        launcher.transport.create_publisher(QUESTION).publish("the cup and the apple")
        assert wait_for(lambda: len(found) == 1 and len(text) == 1)
    det = found[0]
    assert det.labels == ["cup", "apple"]
    assert det.boxes.tolist() == [[10, 12, 30, 40], [1, 2, 3, 4]]
    assert det.image is not None and det.image.data.shape == (48, 64, 3)
    prompt = client.inputs[0]["query"][-1]["content"]
    assert "the cup and the apple" in prompt and "64x48" in prompt and client.inputs[0]["stream"] is False


def test_pointing_task_publishes_points_and_bad_answers_fail_the_step() -> None:
    client = ScriptedChatClient(['[{"label": "handle", "point": [5, 6]}]', "I cannot see it"])
    vlm = MLLM(inputs=[QUESTION, CAMERA], outputs=[POINTS], model_client=client,
               config=MLLMConfig(task="pointing"), trigger=QUESTION)
    with running(vlm) as launcher:
        points = _collect(launcher, POINTS)
        t = launcher.transport
        t.create_publisher(CAMERA).publish(_frame())
        assert wait_for(lambda: vlm.callbacks["camera"].got_msg)
        t.create_publisher(QUESTION).publish("the handle")
        assert wait_for(lambda: len(points) == 1)
        assert points[0].points.tolist() == [[5, 6]]
        t.create_publisher(QUESTION).publish("the handle again")
        assert wait_for(lambda: vlm.health_status == HealthStatus.ALGORITHM_FAILURE)


def test_structured_task_needs_its_output_type() -> None:
    with pytest.raises(WiringError, match="task 'grounding' publishes Detections"):
        MLLM(inputs=[QUESTION, CAMERA], outputs=[ANSWER], model_client=ScriptedChatClient(),
             config=MLLMConfig(task="grounding"), trigger=QUESTION)
    with pytest.raises(ConfigError):
        MLLMConfig(task="dance")


def test_describe_action_answers_about_the_latest_image() -> None:
    client = ScriptedChatClient(["a red cube"])
    vlm = MLLM(inputs=[QUESTION, CAMERA], outputs=[ANSWER], model_client=client, trigger=QUESTION)
    assert "describe" in vlm.available_actions()
    with running(vlm) as launcher:
        answers = _collect(launcher, ANSWER)
        launcher.transport.create_publisher(CAMERA).publish(_frame())
        assert wait_for(lambda: vlm.callbacks["camera"].got_msg)
        assert vlm.run_on_worker(lambda: vlm.describe("what colour?")) == "a red cube"
        assert wait_for(lambda: answers == ["a red cube"])
    assert client.inputs[0]["query"][-1]["content"] == "what colour?"


# -- router ---------------------------------------------------------------------------------------


def _embed(text: str) -> dict[str, float]:
    words = re.findall(r"[a-z]+", text.lower())
    return {w: words.count(w) / math.sqrt(sum(words.count(v) ** 2 for v in set(words))) for w in set(words)}


class _WordVectorDB(DBClient):
    """A vector database double: bag-of-words unit vectors, cosine distance, nearest first."""

    def __init__(self) -> None:
        super().__init__(db=DB(name="routes"))
        self.rows: dict[str, tuple[str, dict[str, Any]]] = {}

    def _check_connection(self) -> None: ...
    def _initialize(self) -> None: ...
    def _deinitialize(self) -> None: ...

    def _add(self, db_input: dict[str, Any]) -> dict[str, Any]:
        for i, doc, meta in zip(db_input["ids"], db_input["documents"], db_input["metadatas"], strict=True):
            self.rows[i] = (doc, meta)
        return {"ids": list(db_input["ids"])}

    def _conditional_add(self, db_input: dict[str, Any]) -> dict[str, Any]:
        return self._add(db_input)

    def _query(self, db_input: dict[str, Any]) -> dict[str, Any]:
        q = _embed(db_input["query"])

        def distance(doc: str) -> float:
            d = _embed(doc)
            return 1.0 - sum(q.get(w, 0.0) * v for w, v in d.items())

        ranked = sorted(self.rows.values(), key=lambda row: distance(row[0]))[: db_input["n_results"]]
        return {"ids": [], "documents": [r[0] for r in ranked], "metadatas": [r[1] for r in ranked],
                "distances": [distance(r[0]) for r in ranked]}

    def _metadata_query(self, db_input: dict[str, Any]) -> dict[str, Any]:
        return {"ids": [], "documents": [], "metadatas": []}


GOTO, CHAT, FALLBACK = Topic("goto", "String"), Topic("chat", "String"), Topic("unsure", "String")
ROUTES = [Route(routes_to=GOTO, samples=["go to the kitchen", "drive to the door", "move to the table"]),
          Route(routes_to=CHAT, samples=["how are you", "tell me a joke", "what is your name"])]
DEFAULT = Route(routes_to=FALLBACK, samples=["anything else"])
REQUESTS = Topic("requests", "String")


def _route_all(router: SemanticRouter, texts: list[str]) -> dict[str, list[str]]:
    with running(router) as launcher:
        got = {t.name: _collect(launcher, t) for t in (GOTO, CHAT, FALLBACK)}
        pub = launcher.transport.create_publisher(REQUESTS)
        for text in texts:
            pub.publish(text)
        assert wait_for(lambda: sum(len(v) for v in got.values()) == len(texts))
    return got


def test_router_vector_mode_picks_the_nearest_route_and_falls_back() -> None:
    db = _WordVectorDB()
    router = SemanticRouter(inputs=[REQUESTS], routes=ROUTES, default_route=DEFAULT, db_client=db,
                            config=SemanticRouterConfig(router_name="nav", maximum_distance=0.6))
    assert router.mode == "vector"
    got = _route_all(router, ["please go to the kitchen now", "tell me a joke please", "banana"])
    assert got == {"goto": ["please go to the kitchen now"], "chat": ["tell me a joke please"], "unsure": ["banana"]}
    assert len(db.rows) == 7 and {m["route_name"] for _, m in db.rows.values()} == {"goto", "chat", "unsure"}
    assert router.routed == {"goto": 1, "chat": 1, "unsure": 1}


def test_a_router_whose_database_is_down_at_configure_runs_no_fallback() -> None:
    """Review s9 #5, the router as the LLM: its database (a Chroma client, nobody on the port) down at configure
    leaves it up and COMPONENT_FAILURE, and runs none of its fallbacks."""
    embedder = GenericHTTPClient(GenericLLM(name="embeddings", checkpoint="embeddings"), port=free_tcp_port())
    db = ChromaClient(ChromaDB(name="routes", collection_name="routes"), port=free_tcp_port(),
                      embedding_client=embedder)
    router = SemanticRouter(inputs=[REQUESTS], routes=ROUTES, default_route=DEFAULT, db_client=db,
                            config=SemanticRouterConfig(router_name="nav"))
    ran: list[str] = []
    router.on_component_fail(Action(ran.append, args=("fallback",)))
    with running(router) as launcher:
        assert launcher.all_active()
        assert router.health_status == HealthStatus.COMPONENT_FAILURE, router.health_status
        assert "ClientConnectionError" in router.health_message
        assert ran == []


def test_router_llm_mode_offers_one_tool_per_route() -> None:
    def choose(inp: dict[str, Any]) -> dict[str, Any]:
        text = inp["query"][-1]["content"]
        if "kitchen" in text:
            return tool_call("route_to_goto", {}, "r1")
        if "joke" in text:
            return tool_call("route_to_chat", {}, "r2")
        return {"output": "no idea"}

    client = ScriptedChatClient([choose])
    router = SemanticRouter(inputs=[REQUESTS], routes=ROUTES, default_route=DEFAULT, model_client=client)
    assert router.mode == "llm"
    got = _route_all(router, ["drive to the kitchen", "a joke please", "banana"])
    assert got == {"goto": ["drive to the kitchen"], "chat": ["a joke please"], "unsure": ["banana"]}
    names = [t["function"]["name"] for t in client.inputs[0]["tools"]]
    assert names == ["route_to_goto", "route_to_chat", "route_to_unsure"]
    assert "go to the kitchen" in client.inputs[0]["tools"][0]["function"]["description"]


def test_router_wiring_errors() -> None:
    with pytest.raises(WiringError, match="non-empty list of Route"):
        SemanticRouter(inputs=[REQUESTS], routes=[], db_client=_WordVectorDB())
    with pytest.raises(WiringError, match="not both"):
        SemanticRouter(inputs=[REQUESTS], routes=ROUTES, db_client=_WordVectorDB(), model_client=ScriptedChatClient())
    with pytest.raises(WiringError, match="needs a model_client"):
        SemanticRouter(inputs=[REQUESTS], routes=ROUTES)
    with pytest.raises(ConfigError, match="samples"):
        Route(routes_to=GOTO, samples=[])


def test_detections_input_is_prefaced_to_the_question() -> None:
    seen = Topic("seen", "Detections")
    client = ScriptedChatClient(["two things"])
    vlm = MLLM(inputs=[QUESTION, CAMERA, seen], outputs=[ANSWER], model_client=client, trigger=QUESTION)
    with running(vlm) as launcher:
        answers = _collect(launcher, ANSWER)
        t = launcher.transport
        t.create_publisher(seen).publish(DetectionsMsg(boxes=[[0, 0, 1, 1]], labels=["cup"], scores=[0.9]))
        t.create_publisher(CAMERA).publish(_frame())
        assert wait_for(lambda: vlm.callbacks["seen"].got_msg and vlm.callbacks["camera"].got_msg)
        t.create_publisher(QUESTION).publish("what is on the table?")
        assert wait_for(lambda: len(answers) == 1)
    assert client.inputs[0]["query"][-1]["content"] == "Objects detected (seen: cup).\nwhat is on the table?"
