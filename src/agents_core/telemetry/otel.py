"""The OpenTelemetry hooks of one process: spans and metrics, exported over OTLP (imported only when on).

Spans (one trace from a message to the messages it caused, across processes):

- ``receive <topic>`` (CONSUMER): a value reaching a component's input; its parent is the
  ``publish`` span of the sender, carried with the message (:mod:`agents_core.telemetry.carrier`);
- ``step <component>``: one execution step, a child of the receive that triggered it (a timed
  step starts a trace of its own);
- ``publish <topic>`` (PRODUCER): a value sent; its context goes with the message;
- ``model <name>`` (CLIENT): one model call with ``gen_ai.*`` attributes (model, client, tokens
  in and out where the client reports them, time to first token for a stream);
- ``tool <name>``, ``action <name>``, ``goal <action>``: tool calls, actions, goals.

They are recorded by :mod:`agents_core.telemetry.spans` (a tuple each, on the hot thread), turned
into ``ReadableSpan`` and exported in batches from a thread of this module
(``OTEL_BSP_SCHEDULE_DELAY``, ``OTEL_BSP_MAX_EXPORT_BATCH_SIZE``, ``OTEL_BSP_MAX_QUEUE_SIZE``)
through the OTLP exporter of the chosen protocol; that thread yields the GIL every few dozen spans.

Metrics (the SDK's ``MeterProvider``, exported every ``OTEL_METRIC_EXPORT_INTERVAL``):
``agents.step.duration`` (histogram, s, per component), ``agents.model.duration`` and
``agents.model.time_to_first_token`` (histograms, s, per model), ``agents.topic.published`` /
``.delivered`` / ``.dropped`` (per topic) and ``agents.component.steps`` /
``agents.component.queue_depth`` (per component), read from the counters the runtime keeps anyway,
``agents.telemetry.spans_dropped``, ``process.cpu.time`` and ``process.memory.usage``. A step's
duration costs a deque append on the step's thread; the histogram gets them at each collection.
"""

from __future__ import annotations

import collections
import contextlib
import os
import threading
import time
import typing
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

from opentelemetry.metrics import CallbackOptions, Observation
from opentelemetry.sdk.metrics import MeterProvider
from opentelemetry.sdk.metrics.export import PeriodicExportingMetricReader
from opentelemetry.sdk.resources import Resource
from opentelemetry.sdk.trace import ReadableSpan
from opentelemetry.sdk.util.instrumentation import InstrumentationScope
from opentelemetry.trace import SpanContext, SpanKind, Status, StatusCode, TraceFlags

from . import switch
from .process import process_figures
from .settings import TelemetrySettings
from .spans import (
    ATTRIBUTES,
    CLIENT,
    CONSUMER,
    INTERNAL,
    KIND,
    NAME,
    PARENT,
    PARENT_REMOTE,
    PRODUCER,
    SAMPLED,
    SPAN,
    START,
    TRACE,
    Context,
    FinishedSpan,
    SpanRecorder,
    parse_traceparent,
    sampling_ratio,
)

__all__ = ["OtelHooks"]

_KINDS = {k.value: k for k in SpanKind}
_SAMPLED = TraceFlags(TraceFlags.SAMPLED)
_SCOPE = InstrumentationScope("agents_core")
_UNSET = Status(StatusCode.UNSET)
_MASK64 = (1 << 64) - 1
#: Spans turned into ReadableSpan between two yields of the GIL on the exporter's thread.
_CHUNK = 32


def _exporters(settings: TelemetrySettings) -> tuple[Any, Any]:
    protocol = settings.resolved_protocol()
    endpoint = settings.endpoint
    if protocol == "grpc":
        from opentelemetry.exporter.otlp.proto.grpc.metric_exporter import OTLPMetricExporter  # noqa: PLC0415
        from opentelemetry.exporter.otlp.proto.grpc.trace_exporter import OTLPSpanExporter  # noqa: PLC0415
        if endpoint:
            return OTLPSpanExporter(endpoint=endpoint), OTLPMetricExporter(endpoint=endpoint)
        return OTLPSpanExporter(), OTLPMetricExporter()
    from opentelemetry.exporter.otlp.proto.http.metric_exporter import (  # noqa: PLC0415
        OTLPMetricExporter as HttpMetricExporter,
    )
    from opentelemetry.exporter.otlp.proto.http.trace_exporter import (  # noqa: PLC0415
        OTLPSpanExporter as HttpSpanExporter,
    )
    if endpoint:
        base = endpoint.rstrip("/")
        return HttpSpanExporter(endpoint=f"{base}/v1/traces"), HttpMetricExporter(endpoint=f"{base}/v1/metrics")
    return HttpSpanExporter(), HttpMetricExporter()


def _env_int(name: str, default: int) -> int:
    try:
        return max(1, int(os.environ.get(name, default)))
    except ValueError:
        return default


class _ModelCall:
    """The span of one model call; :meth:`record` reads the result (tokens, a stream's first token).

    A streamed answer's span outlives the call: it is no longer current once the call returns (the
    step goes on under its own span) and ends with the stream, when it is exhausted, closed,
    fails, or is dropped unfinished.
    """

    def __init__(self, hooks: OtelHooks, model: str, client: str) -> None:
        self._hooks = hooks
        self._attributes = {"gen_ai.request.model": model, "gen_ai.system": client}
        self._span: Context | None = None
        self._start = 0.0
        self._streaming = False

    def __enter__(self) -> _ModelCall:
        self._start = time.perf_counter()
        self._span = self._hooks.recorder.begin(f"model {self._attributes['gen_ai.request.model']}", CLIENT,
                                                dict(self._attributes))
        return self

    def set_attribute(self, key: str, value: Any) -> None:
        """Add an attribute (nothing when the span is not sampled)."""
        span = self._span
        if span is not None and span[SAMPLED]:
            span[ATTRIBUTES][key] = value

    def record(self, result: Any, usage: Mapping[str, Any] | None = None) -> Any:
        """Add what ``result`` (and the client's ``usage``) tell; returns the result, its stream wrapped."""
        tokens_in, tokens_out = _tokens(result, usage)
        if tokens_in is not None:
            self.set_attribute("gen_ai.usage.input_tokens", tokens_in)
        if tokens_out is not None:
            self.set_attribute("gen_ai.usage.output_tokens", tokens_out)
        output = result.get("output") if isinstance(result, Mapping) else None
        if output is not None and not isinstance(output, str | bytes) and isinstance(output, Iterator):
            self._streaming = True
            result["output"] = _TimedStream(self, output)
        return result

    def first_chunk(self) -> None:
        ttft = time.perf_counter() - self._start
        self.set_attribute("gen_ai.response.time_to_first_token", ttft)
        self._hooks.ttft.record(ttft, self._attributes)

    def stream_ended(self, chunks: int, exc: BaseException | None) -> None:
        self.set_attribute("gen_ai.response.chunks", chunks)
        self._hooks.model_duration.record(time.perf_counter() - self._start, self._attributes)
        self._hooks.recorder.finish(self._span, exc)

    def __exit__(self, kind: Any, exc: Any, tb: Any) -> None:
        if exc is not None or not self._streaming:
            self._hooks.model_duration.record(time.perf_counter() - self._start, self._attributes)
            self._hooks.recorder.end(self._span, exc)
        else:  # a stream's span ends with the stream (see _TimedStream); the caller's context is back
            self._hooks.recorder.detach(self._span)


class _TimedStream(Iterator[Any]):
    """A model's stream that ends its call's span once: exhausted, failed, closed or dropped."""

    def __init__(self, call: _ModelCall, chunks: Iterator[Any]) -> None:
        self._call: _ModelCall | None = call
        self._chunks = chunks
        self._count = 0

    def __next__(self) -> Any:
        call = self._call
        if call is None:
            raise StopIteration
        try:
            chunk = next(self._chunks)
        except StopIteration:
            self._end(None)
            raise
        except BaseException as exc:
            self._end(exc)
            raise
        if self._count == 0:
            call.first_chunk()
        self._count += 1
        return chunk

    def close(self) -> None:
        """Stop here: the span ends (and the underlying stream is closed, if it can be)."""
        if self._call is not None:
            self._end(None)
        close = getattr(self._chunks, "close", None)
        if close is not None:
            close()

    def _end(self, exc: BaseException | None) -> None:
        call, self._call = self._call, None
        if call is not None:
            call.stream_ended(self._count, exc)

    def __del__(self) -> None:  # dropped unfinished: the span still ends (no current context touched)
        if getattr(self, "_call", None) is not None:
            self._end(None)


def _tokens(result: Any, usage: Mapping[str, Any] | None) -> tuple[int | None, int | None]:
    """Input and output token counts from an Ollama-like result or an OpenAI-like ``usage``."""
    sources: list[Mapping[str, Any]] = [m for m in (usage, result) if isinstance(m, Mapping)]
    if isinstance(result, Mapping) and isinstance(result.get("usage"), Mapping):
        sources.append(result["usage"])
    tokens_in = tokens_out = None
    for source in sources:
        for key in ("prompt_tokens", "input_tokens", "prompt_eval_count"):
            if isinstance(source.get(key), int):
                tokens_in = source[key]
        for key in ("completion_tokens", "output_tokens", "eval_count"):
            if isinstance(source.get(key), int):
                tokens_out = source[key]
    return tokens_in, tokens_out


class OtelHooks:
    """Spans and metrics of this process, exported over OTLP (see the module docstring)."""

    def __init__(self, settings: TelemetrySettings, service_name: str, component: str | None = None) -> None:
        attributes: dict[str, Any] = {"process.pid": os.getpid()}
        if component:
            attributes["agents.component"] = component
        if settings.service_name or not os.environ.get("OTEL_SERVICE_NAME"):
            attributes["service.name"] = settings.service_name or service_name
        self._resource = Resource.create(attributes)
        self._span_exporter, metric_exporter = _exporters(settings)
        self.recorder = SpanRecorder(sampling_ratio(settings.sample_ratio), _env_int("OTEL_BSP_MAX_QUEUE_SIZE", 8192))
        self.recorder.batch_size = _env_int("OTEL_BSP_MAX_EXPORT_BATCH_SIZE", 512)
        self._delay_s = _env_int("OTEL_BSP_SCHEDULE_DELAY", 5000) / 1000.0
        # A span's name and attributes per topic or component, by verb (made once, shared, never changed).
        self._named: dict[str, dict[str, tuple[str, dict[str, Any]]]] = {"receive": {}, "publish": {}, "step": {}}
        self._received, self._published, self._stepped = (self._named[v] for v in ("receive", "publish", "step"))
        self._begin = self.recorder.begin
        self._end = self.end = self.recorder.end  # the hooks' end: the recorder's, no call in between
        self.capture = self.recorder.capture
        self._stop = threading.Event()
        self._export_lock = threading.Lock()
        self._thread = threading.Thread(target=self._export_loop, name="agents-telemetry", daemon=True)
        self._thread.start()
        interval = settings.metrics_interval_s
        reader = PeriodicExportingMetricReader(
            metric_exporter, export_interval_millis=None if interval is None else interval * 1000.0)
        self._meter_provider = MeterProvider(resource=self._resource, metric_readers=[reader])
        meter = self._meter_provider.get_meter("agents_core")
        self._step_durations: collections.deque[tuple[str, float]] = collections.deque(maxlen=100_000)
        self.step_duration = meter.create_histogram("agents.step.duration", unit="s",
                                                    description="time of one execution step")
        self.model_duration = meter.create_histogram("agents.model.duration", unit="s",
                                                     description="time of one model call")
        self.ttft = meter.create_histogram("agents.model.time_to_first_token", unit="s",
                                           description="time to the first chunk of a streamed answer")
        for name in ("published", "delivered", "dropped"):
            meter.create_observable_counter(f"agents.topic.{name}", callbacks=[self._topic_reader(name)],
                                            description=f"values {name} per topic")
        meter.create_observable_gauge("agents.component.queue_depth", callbacks=[self._queue_depths],
                                      description="steps waiting (and running) per component")
        meter.create_observable_counter("agents.component.steps", callbacks=[self._steps],
                                        description="steps run per component")
        meter.create_observable_counter("agents.telemetry.spans_dropped", callbacks=[self._spans_dropped],
                                        description="spans dropped because the export queue was full")
        meter.create_observable_counter("process.cpu.time", unit="s", callbacks=[self._cpu],
                                        description="CPU time of this process")
        meter.create_observable_gauge("process.memory.usage", unit="By", callbacks=[self._rss],
                                      description="resident memory of this process")

    # -- the hooks (agents_core.telemetry.switch.Hooks) ----------------------------------------

    def enter_remote(self, traceparent: str | None) -> object:
        return self.recorder.enter(parse_traceparent(traceparent))

    def leave(self, token: object) -> None:
        self.recorder.leave(token)  # type: ignore[arg-type]  # what enter_remote returned

    def _names(self, verb: str, what: str, attribute: str = "messaging.destination.name") -> tuple[str, dict[str, Any]]:
        """A span's name and attributes, made once per topic or component (shared: never changed)."""
        named = self._named[verb][what] = (f"{verb} {what}", {attribute: what})
        return named

    def receive(self, topic: str) -> object:
        named = self._received.get(topic) or self._names("receive", topic)
        return self._begin(named[0], CONSUMER, named[1])

    def step(self, component: str, context: object) -> object:
        named = self._stepped.get(component) or self._names("step", component, "agents.component")
        return component, time.perf_counter(), self._begin(named[0], INTERNAL, named[1], context)

    def step_end(self, token: object) -> None:
        component, start, span = typing.cast(tuple[str, float, Context | None], token)  # what step returned
        self._step_durations.append((component, time.perf_counter() - start))
        self._end(span)

    def publish(self, topic: str) -> object:
        named = self._published.get(topic) or self._names("publish", topic)
        return self._begin(named[0], PRODUCER, named[1])

    def traceparent(self) -> str | None:
        return self.recorder.traceparent()

    def model_call(self, model: str, client: str) -> _ModelCall:
        return _ModelCall(self, model, client)

    def call(self, kind: str, name: str, attributes: Mapping[str, Any] | None = None) -> Any:
        return self.recorder.span(f"{kind} {name}", attributes={f"agents.{kind}": name, **(attributes or {})})

    # -- spans out ---------------------------------------------------------------------------------

    def _readable(self, finished: FinishedSpan) -> ReadableSpan:
        span, end_ns, error = finished
        trace_id = span[TRACE]
        parent = None
        if span[PARENT]:
            parent = SpanContext(trace_id, span[PARENT] & _MASK64, is_remote=span[PARENT_REMOTE],
                                 trace_flags=_SAMPLED)
        status = Status(StatusCode.ERROR, error) if error is not None else _UNSET
        return ReadableSpan(name=span[NAME], context=SpanContext(trace_id, span[SPAN] & _MASK64, is_remote=False,
                                                                 trace_flags=_SAMPLED),
                            parent=parent, resource=self._resource, attributes=span[ATTRIBUTES],
                            kind=_KINDS.get(span[KIND], SpanKind.INTERNAL), start_time=span[START],
                            end_time=end_ns, status=status, instrumentation_scope=_SCOPE)

    def _export_some(self) -> int:
        with self._export_lock:
            batch = self.recorder.drain(self.recorder.batch_size)
            if batch:
                readable: list[ReadableSpan] = []
                for at in range(0, len(batch), _CHUNK):
                    readable.extend(self._readable(s) for s in batch[at:at + _CHUNK])
                    time.sleep(0)  # the GIL to the hot threads between chunks, not after a whole batch
                with contextlib.suppress(Exception):  # an exporter that fails logs it; the spans are lost
                    self._span_exporter.export(readable)
            return len(batch)

    def _export_loop(self) -> None:
        while not self._stop.is_set():
            self.recorder.ready.wait(self._delay_s)
            self.recorder.ready.clear()
            while self._export_some() >= self.recorder.batch_size and not self._stop.is_set():
                pass

    # -- metrics read at collection ---------------------------------------------------------------

    def _topic_reader(self, field_name: str) -> Any:
        def read(_options: CallbackOptions) -> Iterable[Observation]:
            totals: dict[str, int] = {}
            for transport in {id(r.transport): r.transport for r in switch.live_runtimes() if r.is_bound}.values():
                for topic, stats in transport.statistics().items():
                    totals[topic] = totals.get(topic, 0) + getattr(stats, field_name)
            return [Observation(n, {"messaging.destination.name": t}) for t, n in totals.items()]
        return read

    def _queue_depths(self, _options: CallbackOptions) -> Iterable[Observation]:
        return [Observation(r.worker_statistics().pending, {"agents.component": r.name})
                for r in switch.live_runtimes()]

    def _steps(self, _options: CallbackOptions) -> Iterable[Observation]:
        # The step durations queued since the last collection go into the histogram now.
        durations = self._step_durations
        attributes: dict[str, dict[str, str]] = {}
        while durations:
            name, seconds = durations.popleft()
            self.step_duration.record(seconds, attributes.setdefault(name, {"agents.component": name}))
        return [Observation(r.worker_statistics().executed, {"agents.component": r.name})
                for r in switch.live_runtimes()]

    def _spans_dropped(self, _options: CallbackOptions) -> Iterable[Observation]:
        return [Observation(self.recorder.dropped)]

    def _cpu(self, _options: CallbackOptions) -> Iterable[Observation]:
        return [Observation(process_figures().cpu_seconds)]

    def _rss(self, _options: CallbackOptions) -> Iterable[Observation]:
        return [Observation(process_figures().rss_bytes)]

    # -- the end ---------------------------------------------------------------------------------

    def flush(self, timeout_s: float = 2.0) -> None:
        """Export what is buffered now (bounded)."""
        deadline = time.monotonic() + timeout_s
        while self.recorder.pending() and time.monotonic() < deadline:
            self._export_some()
        self._meter_provider.force_flush(int(timeout_s * 1000))

    def shutdown(self) -> None:
        """Export what is left and stop the exporters' threads."""
        self._stop.set()
        self.recorder.ready.set()
        self._thread.join(timeout=2.0)
        self.flush(2.0)
        self._span_exporter.shutdown()
        self._meter_provider.shutdown(timeout_millis=2000)
