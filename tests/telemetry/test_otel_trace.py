"""Issue 42's acceptance: a question sent to a two-process recipe on Zenoh comes back as one trace.

A real OTLP/HTTP receiver (:mod:`tests.telemetry.otlp_receiver`) on 127.0.0.1 gets, with only
``OTEL_EXPORTER_OTLP_ENDPOINT`` set for the recipe, the spans of both component processes: in
each, the receive, the step, the model call (to the scripted Ollama server) and the publish,
linked parent to child into one trace across the processes (the context travels in the Zenoh
sample's attachment), and the metrics. With the variable unset, nothing reaches the receiver and
the component process has not imported OpenTelemetry.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh")
pytest.importorskip("opentelemetry.sdk")
pytest.importorskip("opentelemetry.exporter.otlp.proto.http")

from agents_core.testing.helpers import wait_for
from agents_core.testing.recipes import RecipeProcess, open_recipe_transport, recipe_environment
from agents_core.topics import Topic

from ..servers.ollama_server import OllamaTestServer
from .otel_recipe import MODEL
from .otlp_receiver import OtlpReceiver, ReceivedSpan

pytestmark = pytest.mark.zenoh

REPO = Path(__file__).resolve().parents[2]
FAST_EXPORT = {"OTEL_BSP_SCHEDULE_DELAY": "100", "OTEL_METRIC_EXPORT_INTERVAL": "300"}


def _ask(tmp_path: Path, env: dict[str, str], server: OllamaTestServer) -> str:
    """Run the recipe, send one question until an answer comes (bounded); the answer."""
    rt = open_recipe_transport("zenoh")
    process = RecipeProcess("tests.telemetry.otel_recipe", [*rt.recipe_args, "--ollama-port", str(server.port)],
                            tmp_path / "recipe.log", cwd=REPO, env=recipe_environment(**env))
    try:
        process.wait_ready(90)
        asker = rt.open_asker()
        answers: list[str] = []
        got = threading.Event()

        def on_answer(msg: Any) -> None:
            answers.append(str(msg))
            got.set()

        asker.create_subscription(Topic("otel/answer", "String"), on_answer)
        question = asker.create_publisher(Topic("otel/question", "String"))
        for _ in range(40):  # until the recipe's subscriber is matched and the chain answers
            question.publish("what is the time?")
            if got.wait(1.5):
                break
        assert answers, f"no answer on otel/answer:\n{process.output()}"
        return answers[0]
    finally:
        rt.close()
        process.stop()


def _one_trace(spans: list[ReceivedSpan]) -> list[ReceivedSpan] | None:
    """The spans of the trace that reached the checker's publish on otel/answer, if complete."""
    for final in spans:
        if final.service == "checker" and final.name == "publish otel/answer":
            return [s for s in spans if s.trace_id == final.trace_id]
    return None


def _child_of(spans: list[ReceivedSpan], child: ReceivedSpan, parent_name: str, service: str) -> ReceivedSpan:
    parents = [s for s in spans if s.span_id == child.parent_id]
    assert parents, f"{child.service}:{child.name} has no parent in the trace"
    assert (parents[0].service, parents[0].name) == (service, parent_name), \
        f"{child.service}:{child.name}'s parent is {parents[0].service}:{parents[0].name}"
    return parents[0]


def test_one_trace_across_two_component_processes(tmp_path: Path) -> None:
    with OtlpReceiver() as receiver, OllamaTestServer(models=[MODEL], reply="noon") as server:
        answer = _ask(tmp_path, {"OTEL_EXPORTER_OTLP_ENDPOINT": receiver.endpoint, **FAST_EXPORT}, server)
        assert "otel=True" in answer
        assert wait_for(lambda: _complete(receiver.spans()), timeout=15, interval=0.1), \
            f"incomplete trace; received: {sorted({(s.service, s.name) for s in receiver.spans()})}"
        trace = _one_trace(receiver.spans())
        assert trace is not None
        by = {(s.service, s.name): s for s in trace}
        # The chain, parent to child, in both processes.
        publish_b = by[("checker", "publish otel/answer")]
        step_b = _child_of(trace, publish_b, "step checker", "checker")
        model_b = by[("checker", "model tiny")]
        assert model_b.parent_id == step_b.span_id
        assert model_b.attributes["gen_ai.request.model"] == "tiny"
        receive_b = _child_of(trace, step_b, "receive otel/mid", "checker")
        publish_a = _child_of(trace, receive_b, "publish otel/mid", "asker")  # across the processes
        step_a = _child_of(trace, publish_a, "step asker", "asker")
        assert by[("asker", "model tiny")].parent_id == step_a.span_id
        receive_a = _child_of(trace, step_a, "receive otel/question", "asker")
        assert receive_a.parent_id == ""  # the test's own publish carried no context: the trace starts here
        assert receive_a.resource["agents.component"] == "asker"
        assert receive_a.resource["process.pid"] != receive_b.resource["process.pid"]
        # Metrics from the component processes.
        wanted = {"agents.step.duration", "agents.model.duration", "agents.topic.published",
                  "agents.component.queue_depth", "process.cpu.time", "process.memory.usage"}
        assert wait_for(lambda: wanted <= receiver.metric_names("checker"), timeout=10, interval=0.1), \
            f"metrics received: {sorted(receiver.metric_names('checker'))}"
        steps = [m for s, m in receiver.metrics("agents.step.duration") if s == "checker"]
        assert any(p.count >= 1 for m in steps for p in m.histogram.data_points)


def _complete(spans: list[ReceivedSpan]) -> bool:
    trace = _one_trace(spans)
    if trace is None:
        return False
    names = {(s.service, s.name) for s in trace}
    return {("asker", "receive otel/question"), ("asker", "step asker"), ("asker", "model tiny"),
            ("asker", "publish otel/mid"), ("checker", "receive otel/mid"), ("checker", "step checker"),
            ("checker", "model tiny"), ("checker", "publish otel/answer")} <= names


def test_off_without_the_variable_nothing_imported_or_sent(tmp_path: Path) -> None:
    with OtlpReceiver() as receiver, OllamaTestServer(models=[MODEL], reply="noon") as server:
        env = {"OTEL_EXPORTER_OTLP_ENDPOINT": "", **FAST_EXPORT}
        answer = _ask(tmp_path, env, server)
        assert "otel=False" in answer  # the component process never imported OpenTelemetry
        assert not wait_for(lambda: receiver.requests > 0, timeout=1.0, interval=0.1)
        assert receiver.spans() == []
