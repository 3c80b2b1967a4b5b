"""The LLM component with a scripted client: prompts, history, streaming, tools, RAG, failures."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest

from agents_core import Launcher, Topic
from agents_core.actions import Action
from agents_core.clients import ChromaClient, DBClient, GenericHTTPClient
from agents_core.components import LLM
from agents_core.components.llm import ThinkStripper
from agents_core.config import LLMConfig
from agents_core.errors import ConfigError, WiringError
from agents_core.messages import DetectionsMsg
from agents_core.models import GenericLLM
from agents_core.status import HealthStatus
from agents_core.testing.helpers import free_tcp_port
from agents_core.vectordbs import DB, ChromaDB

from ..conftest import wait_for
from ..servers.faults import FaultServer
from .scripted_client import ScriptedChatClient, tool_call


@contextmanager
def running(*components: Any) -> Iterator[Launcher]:
    launcher = Launcher("memory")
    launcher.add_pkg(components=list(components))
    with launcher:
        yield launcher


def _collect(launcher: Launcher, topic: Topic) -> list[Any]:
    got: list[Any] = []
    launcher.transport.create_subscription(topic, got.append)
    return got


QUESTION, ANSWER = Topic("question", "String"), Topic("answer", "String")


def _llm(client: ScriptedChatClient, config: LLMConfig | None = None, **kwargs: Any) -> LLM:
    return LLM(inputs=kwargs.pop("inputs", [QUESTION]), outputs=kwargs.pop("outputs", [ANSWER]), model_client=client,
               config=config or LLMConfig(), trigger=kwargs.pop("trigger", QUESTION), **kwargs)


def _ask(launcher: Launcher, texts: list[str], answers: list[Any], expect: int) -> None:
    pub = launcher.transport.create_publisher(QUESTION)
    for text in texts:
        before = len(answers)
        pub.publish(text)
        # One at a time, so each question sees the history of the previous ones.
        assert wait_for(lambda before=before: len(answers) > before or len(answers) >= expect, timeout=5)
    assert wait_for(lambda: len(answers) >= expect, timeout=5)


def test_answers_with_system_prompt_and_inference_params() -> None:
    client = ScriptedChatClient(["Paris."])
    llm = _llm(client, LLMConfig(system_prompt="You are a robot.", temperature=0.2, max_new_tokens=33))
    with running(llm) as launcher:
        answers = _collect(launcher, ANSWER)
        _ask(launcher, ["Capital of France?"], answers, 1)
    assert answers == ["Paris."]
    sent = client.inputs[0]
    assert sent["query"] == [{"role": "system", "content": "You are a robot."},
                             {"role": "user", "content": "Capital of France?"}]
    assert (sent["temperature"], sent["max_new_tokens"], sent["stream"]) == (0.2, 33, False)
    assert "tools" not in sent


def test_history_is_trimmed_and_reset_keeps_the_system_prompt() -> None:
    client = ScriptedChatClient([lambda inp: f"answer {len(client.inputs)}"])
    config = LLMConfig(system_prompt="sys", chat_history=True, history_size=4, history_reset_phrase="chat reset")
    llm = _llm(client, config)
    with running(llm) as launcher:
        answers = _collect(launcher, ANSWER)
        _ask(launcher, ["q1", "q2", "q3"], answers, 3)
        third = client.inputs[2]["query"]
        # system prompt + the two earlier exchanges (4 messages fit history_size=4) + the new question
        assert third == [{"role": "system", "content": "sys"},
                         {"role": "user", "content": "q1"}, {"role": "assistant", "content": "answer 1"},
                         {"role": "user", "content": "q2"}, {"role": "assistant", "content": "answer 2"},
                         {"role": "user", "content": "q3"}]
        assert len(llm.messages) == 4, "history_size bounds the stored messages"
        assert [m["content"] for m in llm.messages] == ["q2", "answer 2", "q3", "answer 3"]
        launcher.transport.create_publisher(QUESTION).publish("Chat Reset")
        assert wait_for(lambda: not llm.messages)
        _ask(launcher, ["q4"], answers, 4)
    assert len(client.inputs) == 4, "the reset phrase is not sent to the model"
    assert client.inputs[3]["query"] == [{"role": "system", "content": "sys"}, {"role": "user", "content": "q4"}]


def test_topic_and_component_templates_use_topic_values() -> None:
    place, detections = Topic("place", "String"), Topic("seen", "Detections")
    client = ScriptedChatClient(["ok"])
    llm = _llm(client, inputs=[QUESTION, place, detections])
    llm.set_topic_prompt(QUESTION, "Answer briefly: {{ question }}")
    llm.set_component_prompt("At the {{ place }} I see {{ seen }}. {{ question }}")
    with running(llm) as launcher:
        answers = _collect(launcher, ANSWER)
        t = launcher.transport
        t.create_publisher(place).publish("kitchen")
        t.create_publisher(detections).publish(DetectionsMsg(boxes=[[0, 0, 1, 1], [1, 1, 2, 2]],
                                                             labels=["cup", "apple"], scores=[0.9, 0.8]))
        assert wait_for(lambda: llm.callbacks["place"].got_msg and llm.callbacks["seen"].got_msg)
        _ask(launcher, ["what is here?"], answers, 1)
    assert client.inputs[0]["query"][-1]["content"] == "At the kitchen I see cup, apple. Answer briefly: what is here?"


def test_template_errors_are_clear() -> None:
    llm = _llm(ScriptedChatClient())
    with pytest.raises(ConfigError, match="not a valid Jinja2 template"):
        llm.set_topic_prompt(QUESTION, "{{ question ")
    with pytest.raises(WiringError, match="not one of its inputs"):
        llm.set_topic_prompt(Topic("other", "String"), "{{ other }}")


def test_a_template_variable_without_a_value_renders_empty_as_upstream() -> None:
    # Issue 26: upstream renders a missing variable empty (jinja2's default) and its recipes rely on it;
    # until then this was an ALGORITHM_FAILURE. Reading into a missing one still fails the step.
    place = Topic("place", "String")
    client = ScriptedChatClient(["ok"])
    llm = _llm(client, inputs=[QUESTION, place])
    llm.set_component_prompt("{{ place }}: {{ question }}")
    with running(llm) as launcher:
        answers = _collect(launcher, ANSWER)
        launcher.transport.create_publisher(QUESTION).publish("hi")
        assert wait_for(lambda: answers == ["ok"])
        llm.set_component_prompt("{{ place.name }}: {{ question }}")
        launcher.transport.create_publisher(QUESTION).publish("hi")
        assert wait_for(lambda: llm.health_status == HealthStatus.ALGORITHM_FAILURE)
    assert [c["query"][-1]["content"] for c in client.inputs] == [": hi"]


def test_streaming_publishes_chunks_then_done_and_sentences() -> None:
    stream_out, sentences = Topic("answer_stream", "StreamingString"), Topic("sentences", "String")
    chunks = ["<think>plan", " the answer</th", "ink>Hello", " there. How", " are you", "? Fine."]
    client = ScriptedChatClient([chunks])
    llm = _llm(client, LLMConfig(stream=True, break_character="."), outputs=[stream_out, sentences])
    with running(llm) as launcher:
        streamed, said = _collect(launcher, stream_out), _collect(launcher, sentences)
        launcher.transport.create_publisher(QUESTION).publish("hi")
        assert wait_for(lambda: bool(streamed) and streamed[-1].done)
        assert wait_for(lambda: len(said) == 2)
    assert client.inputs[0]["stream"] is True
    assert len(streamed) >= 5, "several chunks, then the closing one"
    assert all(m.stream and not m.done for m in streamed[:-1])
    assert streamed[-1].done and streamed[-1].data == ""
    assert "".join(m.data for m in streamed) == "Hello there. How are you? Fine."
    assert said == ["Hello there.", "How are you? Fine."]
    assert client.streams[0].closed, "the stream is released after use"


def test_think_stripper_handles_tags_split_anywhere() -> None:
    text = "a<think>b</think>c<think>d</think>e"
    for size in range(1, len(text) + 1):
        stripper = ThinkStripper()
        out = "".join(stripper.feed(text[i:i + size]) for i in range(0, len(text), size)) + stripper.flush()
        assert out == "ace", size
    unclosed = ThinkStripper()
    assert unclosed.feed("x<think>never closed") + unclosed.flush() == "x"


def test_tool_loop_runs_two_rounds_and_keeps_call_ids() -> None:
    calls: list[tuple[str, Any]] = []

    def get_position(frame: str) -> dict[str, float]:
        calls.append(("get_position", frame))
        return {"x": 1.0, "y": 2.0}

    def move_to(x: float, y: float) -> str:
        calls.append(("move_to", (x, y)))
        return "arrived"

    position_desc = {"type": "function", "function": {
        "name": "get_position", "description": "Where is the robot",
        "parameters": {"type": "object", "properties": {"frame": {"type": "string"}}, "required": ["frame"]}}}
    move_desc = {"name": "move_to", "description": "Drive to x, y",
                 "parameters": {"type": "object", "properties": {"x": {"type": "number"}, "y": {"type": "number"}},
                                "required": ["x", "y"]}}
    client = ScriptedChatClient([tool_call("get_position", {"frame": "map"}, "call_A"),
                                 tool_call("move_to", {"x": 3.0, "y": 4.0}, "call_B"),
                                 "I moved from (1, 2) to (3, 4)."])
    llm = _llm(client)
    llm.register_tool(get_position, position_desc, send_tool_response_to_model=True)
    llm.register_tool(move_to, move_desc, send_tool_response_to_model=True)
    with running(llm) as launcher:
        answers = _collect(launcher, ANSWER)
        _ask(launcher, ["go 2 m further"], answers, 1)
    assert answers == ["I moved from (1, 2) to (3, 4)."]
    assert calls == [("get_position", "map"), ("move_to", (3.0, 4.0))]
    assert [t["function"]["name"] for t in client.inputs[0]["tools"]] == ["get_position", "move_to"]
    last = client.inputs[2]["query"]
    assert [m["role"] for m in last] == ["user", "assistant", "tool", "assistant", "tool"]
    assert last[1]["tool_calls"][0]["id"] == "call_A" and last[2]["tool_call_id"] == "call_A"
    assert last[2]["content"] == '{"x": 1.0, "y": 2.0}'
    assert last[3]["tool_calls"][0]["id"] == "call_B" and last[4]["tool_call_id"] == "call_B"
    assert last[4]["content"] == "arrived"


def test_tool_result_published_directly_when_not_sent_back() -> None:
    def battery() -> str:
        return "battery at 80%"

    client = ScriptedChatClient([tool_call("battery", {}, "c1")])
    llm = _llm(client)
    llm.register_tool(battery, {"name": "battery", "description": "battery level",
                                "parameters": {"type": "object", "properties": {}}})
    with running(llm) as launcher:
        answers = _collect(launcher, ANSWER)
        _ask(launcher, ["battery?"], answers, 1)
    assert answers == ["battery at 80%"]
    assert len(client.inputs) == 1


def test_endless_tool_calls_are_bounded() -> None:
    def ping() -> str:
        return "pong"

    client = ScriptedChatClient([tool_call("ping", {}, "loop")])
    llm = _llm(client, LLMConfig(max_tool_rounds=3))
    llm.register_tool(ping, {"name": "ping", "parameters": {"type": "object", "properties": {}}},
                      send_tool_response_to_model=True)
    with running(llm) as launcher:
        launcher.transport.create_publisher(QUESTION).publish("go")
        assert wait_for(lambda: llm.health_status == HealthStatus.ALGORITHM_FAILURE)
    assert len(client.inputs) == 3


def test_register_tool_checks_the_description() -> None:
    def f() -> None: ...

    llm = _llm(ScriptedChatClient())
    with pytest.raises(ConfigError, match="names 'g' but the function is 'f'"):
        llm.register_tool(f, {"name": "g"})
    with pytest.raises(ConfigError, match="must be callable"):
        llm.register_tool("f", {"name": "f"})  # type: ignore[arg-type]


class _ListDB(DBClient):
    """A vector-database double: keeps documents in a list and returns them all for any query."""

    def __init__(self) -> None:
        super().__init__(db=DB(name="docs"))
        self.docs: list[dict[str, Any]] = []
        self.queries: list[dict[str, Any]] = []

    def _check_connection(self) -> None: ...
    def _initialize(self) -> None: ...
    def _deinitialize(self) -> None: ...

    def _add(self, db_input: dict[str, Any]) -> dict[str, Any]:
        for i, doc in enumerate(db_input["documents"]):
            self.docs.append({"id": db_input["ids"][i], "document": doc,
                              "metadata": (db_input.get("metadatas") or [{}] * len(db_input["ids"]))[i]})
        return {"ids": db_input["ids"]}

    def _conditional_add(self, db_input: dict[str, Any]) -> dict[str, Any]:
        return self._add(db_input)

    def _query(self, db_input: dict[str, Any]) -> dict[str, Any]:
        self.queries.append(db_input)
        hits = self.docs[: db_input["n_results"]]
        return {"ids": [h["id"] for h in hits], "documents": [h["document"] for h in hits],
                "metadatas": [h["metadata"] for h in hits], "distances": [0.0] * len(hits)}

    def _metadata_query(self, db_input: dict[str, Any]) -> dict[str, Any]:
        return {"ids": [], "documents": [], "metadatas": []}


def test_rag_adds_retrieved_documents_to_the_question() -> None:
    db = _ListDB()
    client = ScriptedChatClient(["The charger is in the hall."])
    llm = _llm(client, LLMConfig(enable_rag=True, n_results=1, add_metadata=True, collection_name="house"),
               db_client=db)
    with running(llm) as launcher:
        assert llm.add_documents(ids=["d1"], documents=["The charger is in the hall."],
                                 metadatas=[{"room": "hall"}])
        answers = _collect(launcher, ANSWER)
        _ask(launcher, ["where is the charger?"], answers, 1)
    assert db.queries[0] == {"collection_name": "house", "query": "where is the charger?", "n_results": 1}
    content = client.inputs[0]["query"][-1]["content"]
    assert "The charger is in the hall." in content and '"room": "hall"' in content
    assert content.endswith("where is the charger?")


def test_a_database_down_at_configure_runs_none_of_the_models_fallbacks(caplog: pytest.LogCaptureFixture) -> None:
    """Review s9 #5: the RAG database (a Chroma client on a port nobody listens on) is down at configure; the
    model is fine, so its fallback (switch to the backup client) must not run: unhealthy, the failure said."""
    embedder = GenericHTTPClient(GenericLLM(name="embeddings", checkpoint="embeddings"), port=free_tcp_port())
    db = ChromaClient(ChromaDB(name="notes", collection_name="notes"), port=free_tcp_port(), embedding_client=embedder)
    primary, backup = ScriptedChatClient(["primary"]), ScriptedChatClient(["backup"])
    llm = _llm(primary, LLMConfig(enable_rag=True, collection_name="notes", n_results=1), db_client=db,
               additional_model_clients={"backup": backup}, component_name="librarian")
    llm.on_component_fail(Action(llm.change_model_client, args=("backup",)))
    with caplog.at_level(logging.ERROR), running(llm):
        assert llm.health_status == HealthStatus.COMPONENT_FAILURE, llm.health_status
        assert "ClientConnectionError" in llm.health_message and "ChromaClient" in llm.health_message
        assert llm.model_client is primary
    assert [r for r in caplog.records if "database setup at configure failed (COMPONENT_FAILURE)" in r.getMessage()]


def test_the_database_is_set_up_once_when_two_threads_need_it_at_once() -> None:
    """Review s9 #8: add_documents from two threads (actions, services) while the database, down at configure,
    is back: one setup (initialize), not two."""
    class _SlowDB(_ListDB):
        def __init__(self) -> None:
            super().__init__()
            self.down, self.initialized = True, 0

        def _check_connection(self) -> None:
            if self.down:
                raise ConnectionError("down")

        def _initialize(self) -> None:
            self.initialized += 1
            time.sleep(0.2)  # a setup that takes a while: the second thread arrives meanwhile

    db = _SlowDB()
    llm = _llm(ScriptedChatClient(), LLMConfig(enable_rag=True, collection_name="house"), db_client=db)
    with running(llm):
        assert llm.health_status == HealthStatus.COMPONENT_FAILURE and db.initialized == 0
        db.down = False
        barrier = threading.Barrier(2, timeout=5.0)
        results: list[bool] = []

        def add(i: int) -> None:
            barrier.wait()
            results.append(llm.add_documents(ids=[f"d{i}"], documents=[f"doc {i}"]))

        threads = [threading.Thread(target=add, args=(i,)) for i in range(2)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join(5.0)
        assert results == [True, True] and len(db.docs) == 2
        assert db.initialized == 1, db.initialized


def test_rag_without_a_db_client_is_a_wiring_error() -> None:
    with pytest.raises(WiringError, match="enable_rag needs a db_client"):
        _llm(ScriptedChatClient(), LLMConfig(enable_rag=True))


def test_client_failure_at_run_time_sets_algorithm_failure() -> None:
    llm = _llm(ScriptedChatClient(fail=True))
    with running(llm) as launcher:
        launcher.transport.create_publisher(QUESTION).publish("hi")
        assert wait_for(lambda: llm.health_status == HealthStatus.ALGORITHM_FAILURE)


def test_stalled_stream_ends_with_done_fails_health_and_falls_back() -> None:
    # A real server that sends the first piece of the answer and then nothing; the backup answers.
    stream_out = Topic("answer_stream", "StreamingString")
    with FaultServer(mode="first_chunk_then_stall") as stalled, FaultServer(mode="ok") as working:
        broken = GenericHTTPClient(GenericLLM(name="m", checkpoint="m"), port=stalled.port, inference_timeout=10,
                                   stream_chunk_timeout=0.5)
        backup = GenericHTTPClient(GenericLLM(name="m", checkpoint="m"), port=working.port, inference_timeout=10)
        llm = _llm(broken, LLMConfig(stream=True), outputs=[stream_out],
                   additional_model_clients={"backup": backup})
        # A stream that times out is an inference that failed: ALGORITHM_FAILURE, as upstream.
        llm.on_algorithm_fail(Action(llm.change_model_client, args=("backup",)), max_retries=1)
        with running(llm) as launcher:
            streamed, statuses = _collect(launcher, stream_out), _collect(launcher, llm.status_topic)
            pub = launcher.transport.create_publisher(QUESTION)
            pub.publish("hi")
            # Listeners get their closing message although the answer never finished.
            assert wait_for(lambda: any(m.done for m in streamed), timeout=5)
            assert [(m.data, m.done) for m in streamed] == [("Hello ", False), ("", True)]
            assert wait_for(lambda: any(s.health == "ALGORITHM_FAILURE" for s in statuses))
            failure = next(s for s in statuses if s.health == "ALGORITHM_FAILURE")
            assert "InferenceTimeoutError" in failure.message and "stream_chunk_timeout" in failure.message
            assert wait_for(lambda: llm.model_client is backup), "the fallback switched to the backup"
            streamed.clear()
            pub.publish("again")
            assert wait_for(lambda: any(m.done for m in streamed), timeout=5)
            assert "".join(m.data for m in streamed) == working.reply
            assert wait_for(lambda: llm.health_status == HealthStatus.HEALTHY)
