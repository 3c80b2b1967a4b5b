"""The pieces of telemetry and ``agentsctl top`` on their own: the attachment carrier, the settings, the figures.

And the promise of the issue: with telemetry off (no ``OTEL_EXPORTER_OTLP_ENDPOINT``), a recipe
that runs steps, publishes and calls an action never imports OpenTelemetry.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import threading

import msgpack
import pytest

from agents_core.cli.top_rows import MAX_STATS_BYTES, parse_stats, sort_rows
from agents_core.errors import ConfigError
from agents_core.runtime.figures import percentile
from agents_core.supported_types import ComponentStatus
from agents_core.telemetry.carrier import MAX_ATTACHMENT, append_traceparent, traceparent_of
from agents_core.telemetry.settings import TelemetrySettings, settings_from_env, telemetry_settings
from agents_core.telemetry.spans import (
    INTERNAL,
    PARENT,
    PARENT_REMOTE,
    PRODUCER,
    SAMPLED,
    SPAN,
    TRACE,
    SpanRecorder,
    parse_traceparent,
    sampling_ratio,
)

TRACEPARENT = "00-0af7651916cd43dd8448eb211c80319c-b7ad6b7169203331-01"


def test_the_traceparent_rides_in_a_msgpack_attachment() -> None:
    plain = msgpack.packb({"seq": 7, "stamp_ns": 123})
    carried = append_traceparent(plain, TRACEPARENT)
    assert msgpack.unpackb(carried) == {"seq": 7, "stamp_ns": 123, "traceparent": TRACEPARENT}
    assert traceparent_of(carried) == TRACEPARENT
    assert traceparent_of(plain) is None


@pytest.mark.parametrize("attachment", [
    None, b"", append_traceparent(msgpack.packb({"seq": 1}), TRACEPARENT.replace("b7", "zz")),
    append_traceparent(msgpack.packb({"seq": 1}), TRACEPARENT)[:-3],
    msgpack.packb({"seq": 1}) + b"\xabtraceparent\xd9\x37" + b"0" * (MAX_ATTACHMENT + 1),
    msgpack.packb({"traceparent": 5}),
])
def test_a_malformed_or_oversized_context_is_ignored(attachment: bytes | None) -> None:
    assert traceparent_of(attachment) is None


def test_the_standard_variables_turn_it_on() -> None:
    assert settings_from_env({}) is None
    assert settings_from_env({"OTEL_EXPORTER_OTLP_ENDPOINT": ""}) is None
    assert settings_from_env({"OTEL_EXPORTER_OTLP_ENDPOINT": "http://127.0.0.1:4318"}) == TelemetrySettings()
    assert settings_from_env({"OTEL_EXPORTER_OTLP_TRACES_ENDPOINT": "http://x:4318/v1/traces"}) is not None
    assert settings_from_env({"OTEL_EXPORTER_OTLP_ENDPOINT": "http://x", "OTEL_SDK_DISABLED": "true"}) is None


def test_what_launcher_telemetry_accepts(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("OTEL_EXPORTER_OTLP_ENDPOINT", raising=False)
    monkeypatch.delenv("OTEL_EXPORTER_OTLP_TRACES_ENDPOINT", raising=False)
    assert telemetry_settings(None) is None and telemetry_settings(False) is None
    assert telemetry_settings(True) == TelemetrySettings()
    assert telemetry_settings("http://h:4317").endpoint == "http://h:4317"  # type: ignore[union-attr]
    assert telemetry_settings({"protocol": "grpc"}).protocol == "grpc"  # type: ignore[union-attr]
    monkeypatch.setenv("OTEL_EXPORTER_OTLP_PROTOCOL", "grpc")
    assert TelemetrySettings().resolved_protocol() == "grpc"
    monkeypatch.setenv("OTEL_EXPORTER_OTLP_PROTOCOL", "thrift")
    with pytest.raises(ConfigError, match="OTEL_EXPORTER_OTLP_PROTOCOL='thrift'"):
        TelemetrySettings().resolved_protocol()
    with pytest.raises(ConfigError, match="metrics_interval_s"):
        TelemetrySettings(metrics_interval_s=0)


def test_stats_from_the_network_are_read_bounded() -> None:
    doc = {"steps": 3, "rate_hz": 2.5, "p50_ms": 1.0, "cpu": 0.25, "pid": 9, "evil": "x" * 10, "drops": True}
    assert parse_stats(json.dumps(doc)) == {"steps": 3, "rate_hz": 2.5, "p50_ms": 1.0, "cpu_pct": 25.0, "pid": 9}
    assert parse_stats("") == {} and parse_stats("[1, 2]") == {} and parse_stats("{not json") == {}
    assert parse_stats(json.dumps({"steps": 1, "pad": "x" * MAX_STATS_BYTES})) == {}
    assert parse_stats("[" * 100_000 + "]" * 100_000) == {}


def test_rows_sort_by_a_key_those_without_the_figure_last() -> None:
    rows = [{"component": "b", "rate_hz": 1.0}, {"component": "a"}, {"component": "c", "rate_hz": 5.0}]
    assert [r["component"] for r in sort_rows(rows, "r")] == ["c", "b", "a"]
    assert [r["component"] for r in sort_rows(rows, "n")] == ["a", "b", "c"]
    assert [r["component"] for r in sort_rows(rows, "?")] == ["a", "b", "c"]


def test_percentile_nearest_rank() -> None:
    values = sorted(float(i) for i in range(1, 101))
    assert percentile(values, 0.5) == 51.0 and percentile(values, 0.99) == 99.0 and percentile([], 0.5) == 0.0


_OFF_PROBE = textwrap.dedent("""
    import sys
    from typing import Any
    from agents_core import Component, Launcher, Topic
    from agents_core.actions import Action
    from agents_core.supported_types import String
    from agents_core.testing.helpers import wait_for

    IN, OUT = Topic(name="o/in", msg_type="String"), Topic(name="o/out", msg_type="String")

    class Echo(Component):
        def __init__(self, **kwargs: Any) -> None:
            self.allowed_inputs = {"Required": [String]}
            self.allowed_outputs = {"Required": [String]}
            super().__init__(inputs=[IN], outputs=[OUT], trigger=IN, component_name="echo", **kwargs)
        def _execution_step(self, **kwargs: Any) -> None:
            self.publishers_dict[OUT.name].publish(self.trig_callbacks[IN.name].get_output())
        def poke(self) -> None:
            pass

    echo = Echo()
    launcher = Launcher(transport="memory")
    launcher.add_pkg(components=[echo])
    got = []
    with launcher:
        launcher.transport.create_subscription(OUT, got.append)
        launcher.transport.create_publisher(IN).publish("x")
        assert wait_for(lambda: len(got) == 1, timeout=5)
        Action(echo.poke)()
        status = echo.runtime.figures.document(echo.runtime)
    assert status["steps"] == 1, status
    print(sorted(m for m in sys.modules if m.startswith("opentelemetry")))
""")


def test_off_by_default_nothing_of_opentelemetry_is_imported() -> None:
    env = {k: v for k, v in os.environ.items() if not k.startswith("OTEL_")}
    done = subprocess.run([sys.executable, "-c", _OFF_PROBE], capture_output=True, text=True, timeout=120, env=env,
                          check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "[]"


def test_spans_link_parent_to_child_and_a_remote_parent_is_marked() -> None:
    recorder = SpanRecorder(1.0)
    token = recorder.enter(parse_traceparent(TRACEPARENT))
    with recorder.span("receive"), recorder.span("step"):
        carried = recorder.traceparent()
    recorder.leave(token)
    assert recorder.traceparent() is None
    (step, _, _), (receive, _, _) = recorder.drain(10)
    assert receive[PARENT] == 0xB7AD6B7169203331 and receive[PARENT_REMOTE]
    assert step[PARENT] == receive[SPAN] and not step[PARENT_REMOTE]
    assert step[TRACE] == receive[TRACE] == 0x0AF7651916CD43DD8448EB211C80319C
    assert carried == f"00-{step[TRACE]:032x}-{step[SPAN]:016x}-01"


def test_a_trace_not_sampled_records_nothing_and_says_so_downstream() -> None:
    recorder = SpanRecorder(0.0)
    with recorder.span("receive"), recorder.span("step"):
        carried = recorder.traceparent()
    assert recorder.drain(10) == [] and carried is not None and carried.endswith("-00")
    downstream = SpanRecorder(1.0)  # records everything it starts, but follows the parent's "no"
    token = downstream.enter(parse_traceparent(carried))
    with downstream.span("receive"):
        assert downstream.traceparent() == carried
    downstream.leave(token)
    assert downstream.drain(10) == []
    assert parse_traceparent("00-" + "0" * 32 + "-b7ad6b7169203331-01") is None
    assert parse_traceparent(TRACEPARENT.upper()) is None
    assert sampling_ratio(0.25) == 0.25 and sampling_ratio(7) == 1.0


def test_a_trace_not_sampled_stays_not_sampled_across_a_thread_hand_off() -> None:
    recorder = SpanRecorder(0.5)  # a new trace on the other thread could be sampled: it must not start
    for _ in range(20):
        publish = recorder.begin("publish", PRODUCER, {}, None)
        if publish is not None and not publish[SAMPLED]:
            break
        recorder.end(publish)
    recorder.drain(100)  # the sampled tries
    captured, carried = recorder.capture(), recorder.traceparent()
    assert carried is not None and carried.endswith("-00")
    seen: list[str | None] = []

    def step() -> None:  # the worker: the step's parent is handed over, as the runtime does
        opened = recorder.begin("step", INTERNAL, {}, captured)
        seen.append(recorder.traceparent())
        with recorder.span("publish out"):
            seen.append(recorder.traceparent())
        recorder.end(opened)
        seen.append(recorder.traceparent())

    worker = threading.Thread(target=step)
    worker.start()
    worker.join(5)
    recorder.end(publish)
    assert seen == [carried, carried, None] and recorder.traceparent() is None
    assert recorder.drain(10) == []


def test_the_sampler_variables(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("OTEL_TRACES_SAMPLER", "parentbased_traceidratio")
    monkeypatch.setenv("OTEL_TRACES_SAMPLER_ARG", "0.1")
    assert sampling_ratio() == 0.1
    monkeypatch.setenv("OTEL_TRACES_SAMPLER", "always_off")
    assert sampling_ratio() == 0.0
    monkeypatch.delenv("OTEL_TRACES_SAMPLER")
    assert sampling_ratio() == 1.0


def test_a_status_without_stats_from_an_older_peer_still_decodes() -> None:
    codecs = pytest.importorskip("agents_zenoh.codecs")
    before_stats = bytes.fromhex(  # the ComponentStatus document before issue 42 added "stats"
        "85a9636f6d706f6e656e74a36c6c6daf6c6966656379636c655f7374617465a6616374697665a66865616c7468a74845414c5448"
        "59a76d657373616765a0a668656164657282a87374616d705f6e73cf112210f47de98115a86672616d655f6964a0")
    status = codecs.decode_value(ComponentStatus, before_stats)
    assert (status.component, status.lifecycle_state, status.stats) == ("llm", "active", "")
