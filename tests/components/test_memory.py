"""Memory on the memory transport, on the real emem engine: storage, tools, episodes and every bad input.

The embeddings here come from :class:`WordEmbedder`, a client whose vectors are bags of hashed words
(texts sharing words are near): deterministic and instant. ``test_memory_servers.py`` runs the same
component against a real llama.cpp embedding server.
"""

from __future__ import annotations

import contextlib
import hashlib
import re
from collections.abc import Iterator, MutableMapping
from pathlib import Path
from typing import Any

import pytest

from agents_core import Launcher, MemoryTransport, Topic
from agents_core.clients import GenericHTTPClient, ModelClient
from agents_core.components import LLM, MemLayer, Memory
from agents_core.config import MemoryConfig
from agents_core.errors import ClientConnectionError, ComponentError, ConfigError, RemoteError, WiringError
from agents_core.messages import DetectionsMsg, Header, OdometryMsg, PoseMsg, StreamingStringMsg
from agents_core.models import GenericLLM
from agents_core.status import HealthStatus
from agents_core.testing.helpers import free_tcp_port

from ..conftest import wait_for
from .scripted_client import ScriptedChatClient, tool_call

pytest.importorskip("emem", reason="the memory extra is not installed (pip install 'agents-core[memory]')")

ODOM, POSE = Topic("odom", "Odometry"), Topic("pose", "PoseStamped")
SEEN, HEARD, SAID = Topic("seen", "Detections"), Topic("heard", "String"), Topic("said", "StreamingString")
BATTERY = Topic("battery", "Float32")


class WordEmbedder(ModelClient):
    """Embeddings as hashed bags of words (64 dims); ``down`` fails every call like a dead server."""

    def __init__(self) -> None:
        super().__init__(model=GenericLLM(name="words", checkpoint="words"))
        self.down = False
        self.calls = 0

    def _check_connection(self) -> None:
        if self.down:
            raise ClientConnectionError("word embedder: connection refused")

    def _initialize(self) -> None: ...
    def _deinitialize(self) -> None: ...

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        raise NotImplementedError

    def _embed(self, texts: list[str]) -> list[list[float]]:
        self._check_connection()
        self.calls += 1
        vectors = []
        for text in texts:
            v = [0.0] * 64
            for word in re.findall(r"[a-z]+", text.lower()):
                v[int(hashlib.md5(word.encode()).hexdigest(), 16) % 64] += 1.0
            v[63] += 0.01  # never the zero vector (cosine space)
            vectors.append(v)
        return vectors


def odom(x: float, y: float) -> OdometryMsg:
    return OdometryMsg(pose=PoseMsg(position=[x, y, 0.0]), header=Header(frame_id="map"))


def seen(*labels: str) -> DetectionsMsg:
    return DetectionsMsg(boxes=[[0, 0, 10, 10]] * len(labels), labels=list(labels), scores=[0.9] * len(labels))


def memory(tmp_path: Path, embedder: ModelClient | None = None, layers: list[MemLayer] | None = None,
           **config: Any) -> Memory:
    config.setdefault("db_path", str(tmp_path / "memory.db"))
    config.setdefault("flush_interval", 0.0)
    return Memory(layers=layers or [MemLayer(subscribes_to=SEEN, temporal_change=True), MemLayer(subscribes_to=HEARD)],
                  position=config.pop("position", ODOM), embedding_client=embedder or WordEmbedder(),
                  model_client=config.pop("model_client", None), config=MemoryConfig(**config), trigger=20.0)


@contextlib.contextmanager
def running(*components: Any) -> Iterator[tuple[Launcher, Any]]:
    transport = MemoryTransport()
    launcher = Launcher(transport)
    launcher.add_pkg(components=list(components))
    try:
        with launcher:
            yield launcher, lambda topic, value: transport.create_publisher(topic).publish(value)
    finally:
        transport.close()


def at(m: Memory, send: Any, x: float, y: float, topic: Topic = ODOM) -> None:
    send(topic, odom(x, y) if topic is ODOM else PoseMsg(position=[x, y, 0.0]))
    assert wait_for(lambda: m._fix is not None and (m._fix.x, m._fix.y) == (x, y))


def settle(m: Memory, stored: int) -> None:
    assert wait_for(lambda: m.stats["stored"] >= stored and m.stats["pending"] == 0, timeout=10), m.stats


def test_observations_are_stored_at_the_robot_s_place_and_found_by_meaning_place_and_time(tmp_path: Path) -> None:
    m = memory(tmp_path, layers=[MemLayer(subscribes_to=SEEN, temporal_change=True), MemLayer(subscribes_to=HEARD),
                                 MemLayer(subscribes_to=SAID, template="someone said: {{ text }}")])
    with running(m) as (launcher, send):
        at(m, send, 4.0, 2.0)
        send(SEEN, seen("cup", "chair"))
        send(HEARD, "a doorbell ringing")
        for chunk, done in (("hello ", False), ("robot", True)):
            send(SAID, StreamingStringMsg(data=chunk, stream=True, done=done))
        settle(m, 3)
        at(m, send, -3.0, 7.0)
        send(HEARD, "a kettle whistling in the kitchen")
        settle(m, 4)
        found = m.semantic_search(query="kettle kitchen", n_results=1)
        assert "kettle whistling" in found and "doorbell" not in found
        near = m.spatial_query(x=4.0, y=2.0, radius=0.5)
        assert "cup, chair" in near and "someone said: hello robot" in near and "kettle" not in near
        assert "kettle" in m.temporal_query(last_n_minutes=5)
        where = m.locate(concept="kettle whistling kitchen", n_results=1)
        assert "-3.0" in where and "7.0" in where
        # Through the execute_method service, as a planner in another process calls it.
        reply = launcher.transport.request(f"{m.component_name}/execute_method",
                                           {"method": "semantic_search", "kwargs": {"query": "doorbell"}})
        assert "doorbell" in reply["result"]
    assert m.stats == {"stored": 4, "no_position": 0, "unchanged": 0, "dropped": 0, "unreadable": 0, "refused": 0,
                       "embed_errors": 0, "store_errors": 0, "pending": 0}
    assert m.health_status == HealthStatus.HEALTHY


def test_temporal_layers_store_every_value_others_skip_the_same_value_at_the_same_place(tmp_path: Path) -> None:
    m = memory(tmp_path, layers=[MemLayer(subscribes_to=SEEN, temporal_change=True),
                                 MemLayer(subscribes_to=HEARD, resolution_multiple=4)], position=POSE)
    with running(m) as (_, send):
        at(m, send, 0.5, 0.5, POSE)
        for _ in range(2):
            send(SEEN, seen("cup"))
            send(HEARD, "the living room")
            assert wait_for(lambda: m.stats["stored"] + m.stats["unchanged"] >= 2)
        assert wait_for(lambda: m.stats["stored"] + m.stats["unchanged"] == 4)
        at(m, send, 3.5, 0.5, POSE)  # 3 m on: the same 4 m cell of the room layer
        send(HEARD, "the living room")
        assert wait_for(lambda: m.stats["unchanged"] == 2)
        at(m, send, 4.5, 0.5, POSE)  # the next cell: stored again
        send(HEARD, "the living room")
        settle(m, 4)
    assert m.stats["stored"] == 4 and m.stats["unchanged"] == 2


def test_internal_state_layers_answer_body_status(tmp_path: Path) -> None:
    m = memory(tmp_path, layers=[MemLayer(subscribes_to=HEARD), MemLayer(subscribes_to=BATTERY,
                                                                        is_internal_state=True)])
    with running(m) as (_, send):
        at(m, send, 1.0, 1.0)
        send(BATTERY, 0.42)
        settle(m, 1)
        status = m.body_status()
        assert "battery" in status and "0.42" in status
        assert "0.42" in m.body_status(layers=["battery"])


def test_a_position_that_never_arrives_stores_nothing_counts_it_and_says_so(tmp_path: Path) -> None:
    m = memory(tmp_path, position_timeout=0.3)
    with running(m) as (_, send):
        send(HEARD, "nobody knows where")
        assert wait_for(lambda: m.stats["no_position"] == 1)
        assert wait_for(lambda: m.health_status == HealthStatus.ALGORITHM_FAILURE)
        assert "no position on 'odom'" in m.health_message
        with pytest.raises(ComponentError, match="no position"):
            m.store()
        with pytest.raises(ComponentError, match="no recent position"):
            m.store_specific_memory("a note")
        assert m.store_specific_memory("the charger is here", x=1.0, y=2.0) is True
        at(m, send, 0.0, 0.0)  # a position now: the next value is stored, health recovers
        send(HEARD, "found myself")
        settle(m, 2)
        assert wait_for(lambda: m.health_status == HealthStatus.HEALTHY)
    assert m.stats["stored"] == 2


def test_an_embedding_server_that_is_down_is_a_typed_error_the_values_wait_and_are_written_later(
        tmp_path: Path) -> None:
    embedder = WordEmbedder()
    embedder.down = True
    m = memory(tmp_path, embedder)
    with running(m) as (_, send):
        assert m.health_status == HealthStatus.COMPONENT_FAILURE
        assert "ClientConnectionError" in m.health_message
        at(m, send, 1.0, 1.0)
        send(HEARD, "waiting for the server")
        assert wait_for(lambda: m.stats["pending"] == 1 and m.stats["embed_errors"] >= 2)
        assert m.health_status == HealthStatus.COMPONENT_FAILURE
        embedder.down = False
        settle(m, 1)
        assert wait_for(lambda: m.health_status == HealthStatus.HEALTHY)
        assert "waiting for the server" in m.semantic_search(query="server")


def test_a_real_http_embedding_client_whose_server_is_down_fails_typed_and_loses_nothing(tmp_path: Path) -> None:
    client = GenericHTTPClient(GenericLLM(name="embed", checkpoint="nothing"), port=free_tcp_port(),
                               inference_timeout=2)
    m = memory(tmp_path, client, buffer_size=2)
    with running(m) as (_, send):
        assert m.health_status == HealthStatus.COMPONENT_FAILURE
        at(m, send, 1.0, 1.0)
        for text in ("one", "two", "three"):
            send(HEARD, text)
            assert wait_for(lambda t=text: m._last_stored.get("heard", ("",))[0] == t)
        assert wait_for(lambda: m.stats["pending"] == 2 and m.stats["dropped"] == 1)
        assert "ClientConnectionError" in m.health_message or "Connect" in m.health_message


def test_a_database_path_that_cannot_be_written_is_a_typed_error_and_the_values_are_retried(tmp_path: Path) -> None:
    blocker = tmp_path / "not_a_directory"
    blocker.write_text("a file where the database's folder should be")
    m = memory(tmp_path, db_path=str(blocker / "memory.db"))
    with running(m) as (_, send):
        assert m.health_status == HealthStatus.COMPONENT_FAILURE
        assert "MemoryStoreError" in m.health_message and "cannot open" in m.health_message
        at(m, send, 2.0, 3.0)
        send(HEARD, "kept until the disk is back")
        assert wait_for(lambda: m.stats["pending"] == 1 and m.stats["store_errors"] >= 2)
        blocker.unlink()
        blocker.mkdir()
        settle(m, 1)
        assert wait_for(lambda: m.health_status == HealthStatus.HEALTHY)
    assert (blocker / "memory.db").is_file() and (blocker / "memory.hnsw.bin").is_file()


def test_memory_survives_a_restart_of_the_component(tmp_path: Path) -> None:
    first = memory(tmp_path)
    with running(first) as (_, send):
        at(first, send, 5.0, 5.0)
        send(HEARD, "the red toolbox is under the stairs")
        settle(first, 1)
    second = memory(tmp_path)
    with running(second):
        found = second.semantic_search(query="red toolbox")
        assert "under the stairs" in found and "5.0" in found
        assert second.stats["stored"] == 0


def test_episodes_are_consolidated_by_concatenation_or_by_the_model_client(tmp_path: Path) -> None:
    m = memory(tmp_path)
    with running(m) as (_, send):
        at(m, send, 1.0, 1.0)
        episode = m.start_episode("kitchen patrol")
        assert m.store_specific_memory("saw a cat on the table") is True
        assert m.store_specific_memory("the fridge door was open") is True
        assert m.end_episode() == episode
        summary = m.episode_summary(task_name="kitchen patrol")
        assert "kitchen patrol" in summary and "cat on the table" in summary and "fridge door" in summary
        assert m.end_episode() == "No active episode"

    def answer(inference_input: dict[str, Any]) -> str:
        prompt = inference_input["query"][-1]["content"]
        return '[{"name": "cat", "entity_type": "object"}]' if "JSON array" in prompt else \
            "The robot patrolled the kitchen and saw a cat."

    model = ScriptedChatClient([answer])
    m2 = memory(tmp_path, model_client=model, db_path=str(tmp_path / "with_model.db"))
    with running(m2) as (_, send):
        at(m2, send, 1.0, 1.0)
        m2.start_episode("patrol")
        m2.store_specific_memory("saw a cat on the table")
        m2.end_episode()
        assert "patrolled the kitchen" in m2.episode_summary(last_n=1)
        assert "patrolled the kitchen" in m2.search_gists(query="kitchen cat")
        assert "cat" in m2.entity_query(name="cat")


def test_tool_arguments_are_checked_against_their_schema_before_anything_runs(tmp_path: Path) -> None:
    m = memory(tmp_path)
    actions = m.available_actions()
    for name in ("semantic_search", "spatial_query", "temporal_query", "episode_summary", "get_current_context",
                 "search_gists", "entity_query", "locate", "recall", "body_status", "store", "start_episode",
                 "end_episode", "store_specific_memory"):
        assert actions[name]["function"]["name"] == name
        assert actions[name]["function"]["parameters"]["type"] == "object"
    with running(m) as (launcher, _):
        with pytest.raises(ComponentError, match="unknown argument"):
            m.semantic_search(query="x", colour="red")
        with pytest.raises(ComponentError, match="missing required"):
            m.spatial_query(x=1.0)
        with pytest.raises(ComponentError, match="must be a number"):
            m.spatial_query(x="here", y=1.0)
        with pytest.raises(RemoteError, match="unknown argument"):
            launcher.transport.request(f"{m.component_name}/execute_method",
                                       {"method": "locate", "kwargs": {"thing": "cup"}})
        assert "No" in m.search_gists(query="anything", time_after=0)


def test_register_tools_on_lets_an_llm_call_them(tmp_path: Path) -> None:
    m = memory(tmp_path)
    question, answer = Topic("question", "String"), Topic("answer", "String")
    client = ScriptedChatClient([tool_call("locate", {"concept": "charging dock", "n_results": 1}, "call_1")])
    llm = LLM(inputs=[question], outputs=[answer], model_client=client, trigger=question)
    m.register_tools_on(llm, tools=["locate", "semantic_search"], send_tool_response_to_model=False)
    assert sorted(llm._tools) == ["locate", "semantic_search"]
    with pytest.raises(ConfigError, match="no memory tool"):
        m.register_tools_on(llm, tools=["teleport"])
    with running(m, llm) as (launcher, send):
        at(m, send, 8.0, -2.0)
        send(HEARD, "the charging dock")
        settle(m, 1)
        answers: list[str] = []
        launcher.transport.create_subscription(answer, answers.append)
        send(question, "where is the charging dock?")
        assert wait_for(lambda: bool(answers))
    assert "8.0" in answers[0] and "-2.0" in answers[0]


def test_wiring_errors_are_refused_at_construction(tmp_path: Path) -> None:
    with pytest.raises(WiringError, match="perception layer"):
        MemLayer(subscribes_to=ODOM)
    with pytest.raises(WiringError, match="embedding_client"):
        Memory(layers=[MemLayer(subscribes_to=HEARD)], position=ODOM, embedding_client=ScriptedChatClient())
    with pytest.raises(WiringError, match="Odometry or PoseStamped"):
        Memory(layers=[MemLayer(subscribes_to=HEARD)], position=HEARD, embedding_client=WordEmbedder())
    with pytest.raises(WiringError, match="distinct"):
        memory(tmp_path, layers=[MemLayer(subscribes_to=HEARD), MemLayer(subscribes_to=HEARD)])
    with pytest.raises(ConfigError):
        MemoryConfig(db_path="")
    with pytest.raises(ConfigError):
        MemLayer(subscribes_to=HEARD, resolution_multiple=0)
