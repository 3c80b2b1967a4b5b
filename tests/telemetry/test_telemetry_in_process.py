"""Telemetry in one process: ``Launcher(telemetry=...)`` on the memory transport, over http/protobuf and grpc.

On memory the context goes with the value itself: the subscriber's receive runs inside the
publisher's publish span (delivery is synchronous for component inputs), so a chain of two
components is one trace. Each test turns telemetry off again (:func:`agents_core.telemetry.shutdown`).
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip("opentelemetry.sdk")
pytest.importorskip("opentelemetry.exporter.otlp.proto.http")

from agents_core import Component, Launcher, Topic, telemetry
from agents_core.actions import Action
from agents_core.clients.payloads import ChunkStream
from agents_core.errors import ConfigError
from agents_core.launch.spec import ComponentSpec
from agents_core.supported_types import String
from agents_core.telemetry import switch
from agents_core.testing.helpers import wait_for

from ..components.scripted_client import ScriptedChatClient
from .otlp_receiver import OtlpGrpcReceiver, OtlpReceiver, ReceivedSpan

IN, MID, OUT = Topic(name="t/in", msg_type="String"), Topic(name="t/mid", msg_type="String"), \
    Topic(name="t/out", msg_type="String")


class Upper(Component):
    """Upper-cases each text; ``note()`` is an action."""

    def __init__(self, source: Topic, target: Topic, component_name: str, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Required": [String]}
        super().__init__(inputs=[source], outputs=[target], trigger=source, component_name=component_name, **kwargs)
        self.notes = 0

    def _execution_step(self, **kwargs: Any) -> None:
        text = self.trig_callbacks[self.inputs[0].name].get_output()
        self.publishers_dict[self.outputs[0].name].publish(text.upper())

    def note(self) -> None:
        self.notes += 1


@pytest.fixture(autouse=True)
def _telemetry_off_after() -> Iterator[None]:
    yield
    telemetry.shutdown()
    assert not telemetry.enabled()


def _run_chain(endpoint: str, protocol: str) -> None:
    a, b = Upper(IN, MID, "upper_a"), Upper(MID, OUT, "upper_b")
    launcher = Launcher(transport="memory", telemetry={"endpoint": endpoint, "protocol": protocol,
                                                       "service_name": "chain"})
    launcher.add_pkg(components=[a, b])
    got: list[str] = []
    with launcher:
        assert telemetry.enabled()
        launcher.transport.create_subscription(OUT, lambda v: got.append(str(v)))
        launcher.transport.create_publisher(IN).publish("hi")
        assert wait_for(lambda: got == ["HI"], timeout=5)
        Action(b.note)()
        telemetry.flush()


def _chain_is_one_trace(spans: list[ReceivedSpan]) -> bool:
    finals = [s for s in spans if s.name == "publish t/out"]
    if not finals:
        return False
    trace = {s.span_id: s for s in spans if s.trace_id == finals[0].trace_id}
    names = [finals[0].name]
    span = finals[0]
    while span.parent_id and span.parent_id in trace:
        span = trace[span.parent_id]
        names.append(span.name)
    return names[::-1] == ["publish t/in", "receive t/in", "step upper_a", "publish t/mid", "receive t/mid",
                           "step upper_b", "publish t/out"]


@pytest.mark.parametrize("receiver_class, protocol", [(OtlpReceiver, "http/protobuf"),
                                                      (OtlpGrpcReceiver, "grpc")])
def test_a_memory_chain_is_one_trace(receiver_class: type[OtlpReceiver], protocol: str) -> None:
    if protocol == "grpc":
        pytest.importorskip("opentelemetry.exporter.otlp.proto.grpc")
    with receiver_class() as receiver:
        _run_chain(receiver.endpoint, protocol)
        assert wait_for(lambda: _chain_is_one_trace(receiver.spans()), timeout=10, interval=0.1), \
            sorted((s.name, s.span_id, s.parent_id) for s in receiver.spans())
        assert {s.service for s in receiver.spans()} == {"chain"}
        actions = [s for s in receiver.spans() if s.name == "action note"]
        assert actions and actions[0].attributes["agents.action"] == "note"
        telemetry.shutdown()  # the last metrics go out at shutdown
        assert wait_for(lambda: "agents.step.duration" in receiver.metric_names(), timeout=10, interval=0.1)


def test_bad_settings_are_refused_naming_the_field() -> None:
    with pytest.raises(ConfigError, match="protocol 'udp'"):
        Launcher(transport="memory", telemetry={"protocol": "udp"})
    with pytest.raises(ConfigError, match=r"unknown field\(s\) \['endpont'\]"):
        Launcher(transport="memory", telemetry={"endpont": "http://127.0.0.1:4318"})
    with pytest.raises(ConfigError, match="telemetry must be"):
        Launcher(transport="memory", telemetry=4318)


def test_component_processes_get_the_launchers_settings_in_their_spec() -> None:
    component = Upper(IN, MID, "upper_spec")
    assert ComponentSpec.from_component(component, "zenoh", {}, 0).telemetry is None  # off: nothing carried
    with OtlpReceiver() as receiver:
        assert telemetry.configure_from({"endpoint": receiver.endpoint, "sample_ratio": 0.5})
        spec = ComponentSpec.from_component(component, "zenoh", {}, 0)
        assert spec.telemetry == {"endpoint": receiver.endpoint, "protocol": None, "service_name": None,
                                  "metrics_interval_s": None, "sample_ratio": 0.5}
        assert ComponentSpec.from_dict(spec.to_dict()).telemetry == spec.telemetry  # as the child reads it
        telemetry.shutdown()


def test_a_streamed_model_call_is_not_left_current_and_ends_with_its_stream() -> None:
    client = ScriptedChatClient([["a", "b"]])  # each answer a ChunkStream of two chunks
    with OtlpReceiver() as receiver:
        assert telemetry.configure_from({"endpoint": receiver.endpoint})
        hooks = switch.hooks
        assert hooks is not None
        with hooks.call("action", "read"):  # the stream read in the step that asked for it
            outer = hooks.traceparent()
            result = client.inference({"stream": True})
            assert isinstance(result["output"], ChunkStream)  # still, to the streaming loops that check
            assert hooks.traceparent() == outer  # the model span is not the step's current span
            assert list(result["output"]) == ["a", "b"]
            assert hooks.traceparent() == outer
        with hooks.call("action", "closed"):
            stream = client.inference({"stream": True})["output"]
            assert next(stream) == "a"
            stream.close()
        with hooks.call("action", "late"):
            late = client.inference({"stream": True})["output"]
        assert hooks.traceparent() is None
        assert list(late) == ["a", "b"]  # read after its step: the step's context does not come back
        assert hooks.traceparent() is None
        with hooks.call("action", "abandoned"):
            client.inference({"stream": True})  # never read
            gc.collect()
        assert hooks.traceparent() is None
        telemetry.flush()

        def models() -> dict[str, ReceivedSpan]:
            spans = receiver.spans()
            by_id = {s.span_id: s for s in spans}
            return {by_id[s.parent_id].name: s for s in spans if s.name == "model scripted" and s.parent_id in by_id}

        assert wait_for(lambda: len(models()) == 4, timeout=10, interval=0.1), receiver.spans()
        chunks = {parent: span.attributes.get("gen_ai.response.chunks") for parent, span in models().items()}
        assert chunks == {"action read": 2, "action closed": 1, "action late": 2, "action abandoned": 0}
        assert "gen_ai.response.time_to_first_token" in models()["action read"].attributes
