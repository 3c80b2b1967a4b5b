"""The OpenTelemetry hooks: spans and metrics of one process (imported only when telemetry is on).

Spans (one trace from a message to the messages it caused, across processes):

- ``receive <topic>`` (CONSUMER): a value reaching a component's input; its parent is the
  ``publish`` span of the sender, carried with the message (:mod:`agents_core.telemetry.carrier`);
- ``step <component>``: one execution step, a child of the receive that triggered it (a timed
  step starts a trace of its own);
- ``publish <topic>`` (PRODUCER): a value sent; its context goes with the message;
- ``model <name>`` (CLIENT): one model call with ``gen_ai.*`` attributes (model, client, tokens
  in and out where the client reports them, time to first token for a stream);
- ``tool <name>``, ``action <name>``, ``goal <action>``: tool calls, component actions, goals.

Metrics: ``agents.step.duration`` (histogram, s, per component), ``agents.model.duration`` and
``agents.model.time_to_first_token`` (histograms, s, per model), ``agents.topic.published`` /
``.delivered`` / ``.dropped`` (counters per topic, read from the transports' statistics when
exported), ``agents.component.queue_depth`` (steps waiting per component), ``agents.component.steps``,
``process.cpu.time`` and ``process.memory.usage`` (this process). Reading them costs nothing per
message: they are observed from counters the runtime keeps anyway, at each export.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

from opentelemetry import context as otel_context
from opentelemetry import trace
from opentelemetry.metrics import CallbackOptions, Observation
from opentelemetry.sdk.metrics import MeterProvider
from opentelemetry.sdk.metrics.export import PeriodicExportingMetricReader
from opentelemetry.sdk.resources import Resource
from opentelemetry.sdk.trace import TracerProvider
from opentelemetry.sdk.trace.export import BatchSpanProcessor
from opentelemetry.trace import SpanKind
from opentelemetry.trace.propagation.tracecontext import TraceContextTextMapPropagator

from . import switch
from .process import process_figures
from .settings import TelemetrySettings

__all__ = ["OtelHooks"]

_CONSUMER, _PRODUCER, _CLIENT = SpanKind.CONSUMER, SpanKind.PRODUCER, SpanKind.CLIENT
_INVALID = trace.INVALID_SPAN_CONTEXT


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


class _Timed:
    """A current span that also records its duration in a histogram."""

    __slots__ = ("_attributes", "_cm", "_histogram", "_start")

    def __init__(self, cm: Any, histogram: Any, attributes: Mapping[str, Any]) -> None:
        self._cm = cm
        self._histogram = histogram
        self._attributes = attributes
        self._start = 0.0

    def __enter__(self) -> Any:
        self._start = time.perf_counter()
        return self._cm.__enter__()

    def __exit__(self, *exc: Any) -> Any:
        self._histogram.record(time.perf_counter() - self._start, self._attributes)
        return self._cm.__exit__(*exc)


class _ModelCall:
    """The span of one model call; :meth:`record` reads the result (tokens, a stream's first token)."""

    def __init__(self, hooks: OtelHooks, model: str, client: str) -> None:
        self._hooks = hooks
        self._attributes = {"gen_ai.request.model": model, "gen_ai.system": client}
        self._span: Any = None
        self._start = 0.0
        self._streaming = False

    def __enter__(self) -> _ModelCall:
        self._start = time.perf_counter()
        self._span = self._hooks.tracer.start_span(f"model {self._attributes['gen_ai.request.model']}",
                                                   kind=_CLIENT, attributes=self._attributes)
        return self

    def record(self, result: Any, usage: Mapping[str, Any] | None = None) -> Any:
        """Add what ``result`` (and the client's ``usage``) tell; returns the result, its stream wrapped."""
        span = self._span
        tokens_in, tokens_out = _tokens(result, usage)
        if tokens_in is not None:
            span.set_attribute("gen_ai.usage.input_tokens", tokens_in)
        if tokens_out is not None:
            span.set_attribute("gen_ai.usage.output_tokens", tokens_out)
        output = result.get("output") if isinstance(result, Mapping) else None
        if output is not None and not isinstance(output, str | bytes) and isinstance(output, Iterator):
            self._streaming = True
            result["output"] = self._timed_stream(output)
        return result

    def _timed_stream(self, chunks: Iterator[Any]) -> Iterator[Any]:
        first = True
        count = 0
        try:
            for chunk in chunks:
                if first:
                    first = False
                    ttft = time.perf_counter() - self._start
                    self._span.set_attribute("gen_ai.response.time_to_first_token", ttft)
                    self._hooks.ttft.record(ttft, self._attributes)
                count += 1
                yield chunk
        finally:
            self._span.set_attribute("gen_ai.response.chunks", count)
            self._end()

    def _end(self) -> None:
        self._hooks.model_duration.record(time.perf_counter() - self._start, self._attributes)
        self._span.end()

    def __exit__(self, kind: Any, exc: Any, tb: Any) -> None:
        if exc is not None:
            self._span.record_exception(exc)
            self._span.set_status(trace.Status(trace.StatusCode.ERROR, f"{type(exc).__name__}: {exc}"))
        if exc is not None or not self._streaming:
            self._end()


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
        resource = Resource.create(attributes)
        span_exporter, metric_exporter = _exporters(settings)
        self._tracer_provider = TracerProvider(resource=resource)
        self._tracer_provider.add_span_processor(BatchSpanProcessor(span_exporter))
        interval = settings.metrics_interval_s
        reader = PeriodicExportingMetricReader(
            metric_exporter, export_interval_millis=None if interval is None else interval * 1000.0)
        self._meter_provider = MeterProvider(resource=resource, metric_readers=[reader])
        self.tracer = self._tracer_provider.get_tracer("agents_core")
        meter = self._meter_provider.get_meter("agents_core")
        self.step_duration = meter.create_histogram("agents.step.duration", unit="s",
                                                    description="time of one execution step")
        self.model_duration = meter.create_histogram("agents.model.duration", unit="s",
                                                     description="time of one model call")
        self.ttft = meter.create_histogram("agents.model.time_to_first_token", unit="s",
                                           description="time to the first chunk of a streamed answer")
        for name, read in (("published", "published"), ("delivered", "delivered"), ("dropped", "dropped")):
            meter.create_observable_counter(f"agents.topic.{name}", callbacks=[self._topic_reader(read)],
                                            description=f"values {name} per topic")
        meter.create_observable_gauge("agents.component.queue_depth", callbacks=[self._queue_depths],
                                      description="steps waiting (and running) per component")
        meter.create_observable_counter("agents.component.steps", callbacks=[self._steps],
                                        description="steps run per component")
        meter.create_observable_counter("process.cpu.time", unit="s", callbacks=[self._cpu],
                                        description="CPU time of this process")
        meter.create_observable_gauge("process.memory.usage", unit="By", callbacks=[self._rss],
                                      description="resident memory of this process")
        self._propagator = TraceContextTextMapPropagator()
        self._step_attributes: dict[str, dict[str, str]] = {}

    # -- the hooks (agents_core.telemetry.switch.Hooks) ----------------------------------------

    def enter_remote(self, traceparent: str | None) -> object:
        if not traceparent:
            return None
        return otel_context.attach(self._propagator.extract({"traceparent": traceparent}))

    def leave(self, token: object) -> None:
        if token is not None:
            otel_context.detach(token)  # type: ignore[arg-type]  # the token enter_remote made

    def receive(self, topic: str) -> Any:
        return self.tracer.start_as_current_span(f"receive {topic}", kind=_CONSUMER,
                                                 attributes={"messaging.destination.name": topic})

    def capture(self) -> object:
        return otel_context.get_current()

    def step(self, component: str, context: object) -> Any:
        attributes = self._step_attributes.get(component)
        if attributes is None:
            attributes = self._step_attributes[component] = {"agents.component": component}
        cm = self.tracer.start_as_current_span(f"step {component}", context=context,  # type: ignore[arg-type]
                                               attributes=attributes)
        return _Timed(cm, self.step_duration, attributes)

    def publish(self, topic: str) -> Any:
        return self.tracer.start_as_current_span(f"publish {topic}", kind=_PRODUCER,
                                                 attributes={"messaging.destination.name": topic})

    def traceparent(self) -> str | None:
        ctx = trace.get_current_span().get_span_context()
        if not ctx.is_valid:
            return None
        return f"00-{ctx.trace_id:032x}-{ctx.span_id:016x}-{int(ctx.trace_flags):02x}"

    def model_call(self, model: str, client: str) -> _ModelCall:
        return _ModelCall(self, model, client)

    def call(self, kind: str, name: str, attributes: Mapping[str, Any] | None = None) -> Any:
        return self.tracer.start_as_current_span(f"{kind} {name}", attributes={f"agents.{kind}": name,
                                                                               **(attributes or {})})

    # -- metrics read at export ------------------------------------------------------------------

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
        return [Observation(r.worker_statistics().executed, {"agents.component": r.name})
                for r in switch.live_runtimes()]

    def _cpu(self, _options: CallbackOptions) -> Iterable[Observation]:
        return [Observation(process_figures().cpu_seconds)]

    def _rss(self, _options: CallbackOptions) -> Iterable[Observation]:
        return [Observation(process_figures().rss_bytes)]

    # -- the end ---------------------------------------------------------------------------------

    def flush(self, timeout_s: float = 2.0) -> None:
        """Export what is buffered now (bounded)."""
        millis = int(timeout_s * 1000)
        self._tracer_provider.force_flush(millis)
        self._meter_provider.force_flush(millis)

    def shutdown(self) -> None:
        """Export what is left and stop the exporters' threads."""
        self._tracer_provider.shutdown()
        self._meter_provider.shutdown(timeout_millis=2000)
