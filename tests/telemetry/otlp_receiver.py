"""An OTLP/HTTP receiver for the tests: a real HTTP server on 127.0.0.1 decoding the OTLP protobuf.

``POST /v1/traces`` and ``/v1/metrics`` bodies (``application/x-protobuf``, gzip or not) are
decoded with ``opentelemetry-proto``'s messages and kept: :meth:`OtlpReceiver.spans` flattens the
spans with their service name, :meth:`OtlpReceiver.metric_names` lists the metrics seen. Bodies
over :data:`MAX_BODY` are refused (413).
"""

from __future__ import annotations

import gzip
import threading
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

from opentelemetry.proto.collector.metrics.v1.metrics_service_pb2 import (
    ExportMetricsServiceRequest,
    ExportMetricsServiceResponse,
)
from opentelemetry.proto.collector.trace.v1.trace_service_pb2 import (
    ExportTraceServiceRequest,
    ExportTraceServiceResponse,
)

__all__ = ["MAX_BODY", "OtlpGrpcReceiver", "OtlpReceiver", "ReceivedSpan"]

MAX_BODY = 16 * 1024 * 1024


@dataclass(frozen=True)
class ReceivedSpan:
    """One received span, flattened."""

    service: str
    name: str
    trace_id: str
    span_id: str
    parent_id: str
    attributes: dict[str, Any]
    resource: dict[str, Any]


def _value(any_value: Any) -> Any:
    kind = any_value.WhichOneof("value")
    return getattr(any_value, kind) if kind else None


def _attributes(items: Any) -> dict[str, Any]:
    return {kv.key: _value(kv.value) for kv in items}


class _Handler(BaseHTTPRequestHandler):
    server: _Server

    def log_message(self, format: str, *args: Any) -> None:
        """Quiet."""

    def do_POST(self) -> None:
        length = int(self.headers.get("Content-Length") or 0)
        if length > MAX_BODY:
            self.send_response(413)
            self.send_header("Content-Length", "0")
            self.end_headers()
            return
        body = self.rfile.read(length)
        if self.headers.get("Content-Encoding") == "gzip":
            body = gzip.decompress(body)
        receiver = self.server.receiver
        if self.path == "/v1/traces":
            request: Any = ExportTraceServiceRequest.FromString(body)
            reply = ExportTraceServiceResponse().SerializeToString()
            receiver.add_traces(request)
        elif self.path == "/v1/metrics":
            request = ExportMetricsServiceRequest.FromString(body)
            reply = ExportMetricsServiceResponse().SerializeToString()
            receiver.add_metrics(request)
        else:
            self.send_response(404)
            self.send_header("Content-Length", "0")
            self.end_headers()
            return
        self.send_response(200)
        self.send_header("Content-Type", "application/x-protobuf")
        self.send_header("Content-Length", str(len(reply)))
        self.end_headers()
        self.wfile.write(reply)


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    block_on_close = True

    def __init__(self, receiver: OtlpReceiver) -> None:
        super().__init__(("127.0.0.1", 0), _Handler)
        self.receiver = receiver


class OtlpReceiver:
    """See the module docstring; a context manager (serves on a thread until the block ends)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._spans: list[ReceivedSpan] = []
        self._metrics: list[tuple[str, str, Any]] = []
        self.requests = 0
        self._server = _Server(self)
        self._thread = threading.Thread(target=self._server.serve_forever, kwargs={"poll_interval": 0.05},
                                        name="otlp-receiver", daemon=True)

    @property
    def endpoint(self) -> str:
        """``http://127.0.0.1:PORT`` (what ``OTEL_EXPORTER_OTLP_ENDPOINT`` takes)."""
        return f"http://127.0.0.1:{self._server.server_address[1]}"

    def __enter__(self) -> OtlpReceiver:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._server.shutdown()
        self._server.server_close()
        self._thread.join(timeout=5)

    def add_traces(self, request: Any) -> None:
        found = []
        for resource_spans in request.resource_spans:
            resource = _attributes(resource_spans.resource.attributes)
            service = str(resource.get("service.name", ""))
            for scope in resource_spans.scope_spans:
                for span in scope.spans:
                    found.append(ReceivedSpan(service, span.name, span.trace_id.hex(), span.span_id.hex(),
                                              span.parent_span_id.hex(), _attributes(span.attributes), resource))
        with self._lock:
            self.requests += 1
            self._spans.extend(found)

    def add_metrics(self, request: Any) -> None:
        found = []
        for resource_metrics in request.resource_metrics:
            service = str(_attributes(resource_metrics.resource.attributes).get("service.name", ""))
            for scope in resource_metrics.scope_metrics:
                for metric in scope.metrics:
                    found.append((service, metric.name, metric))
        with self._lock:
            self.requests += 1
            self._metrics.extend(found)

    def spans(self) -> list[ReceivedSpan]:
        """Every span received so far."""
        with self._lock:
            return list(self._spans)

    def metric_names(self, service: str | None = None) -> set[str]:
        """The names of the metrics received so far (of ``service`` only, if given)."""
        with self._lock:
            return {name for s, name, _ in self._metrics if service is None or s == service}

    def metrics(self, name: str) -> list[tuple[str, Any]]:
        """(service, metric message) of each export of metric ``name``."""
        with self._lock:
            return [(s, m) for s, n, m in self._metrics if n == name]


class OtlpGrpcReceiver(OtlpReceiver):
    """The same over OTLP/gRPC: a real ``grpc`` server on 127.0.0.1 with the collector's trace and metrics services."""

    def __init__(self) -> None:
        import concurrent.futures  # noqa: PLC0415

        import grpc  # noqa: PLC0415
        from opentelemetry.proto.collector.metrics.v1 import metrics_service_pb2_grpc  # noqa: PLC0415
        from opentelemetry.proto.collector.trace.v1 import trace_service_pb2_grpc  # noqa: PLC0415

        self._lock = threading.Lock()
        self._spans = []
        self._metrics = []
        self.requests = 0
        receiver = self

        class Traces(trace_service_pb2_grpc.TraceServiceServicer):  # type: ignore[misc]
            def Export(self, request: Any, context: Any) -> Any:
                receiver.add_traces(request)
                return ExportTraceServiceResponse()

        class Metrics(metrics_service_pb2_grpc.MetricsServiceServicer):  # type: ignore[misc]
            def Export(self, request: Any, context: Any) -> Any:
                receiver.add_metrics(request)
                return ExportMetricsServiceResponse()

        self._pool = concurrent.futures.ThreadPoolExecutor(max_workers=2)
        self._grpc = grpc.server(self._pool)
        trace_service_pb2_grpc.add_TraceServiceServicer_to_server(Traces(), self._grpc)
        metrics_service_pb2_grpc.add_MetricsServiceServicer_to_server(Metrics(), self._grpc)
        self._port = self._grpc.add_insecure_port("127.0.0.1:0")

    @property
    def endpoint(self) -> str:
        return f"http://127.0.0.1:{self._port}"

    def __enter__(self) -> OtlpGrpcReceiver:
        self._grpc.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._grpc.stop(grace=None).wait(5)
        self._pool.shutdown(wait=True)
