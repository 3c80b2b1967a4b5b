"""What telemetry costs a hop: the hop benchmark with OpenTelemetry on (OTLP/HTTP to a local receiver) ÷ off.

The same framework relay and pinger as the ``hop`` suite (:mod:`benchmarks.hop`), run in pairs
that differ only in their environment: ``OTEL_EXPORTER_OTLP_ENDPOINT`` set to a receiver in this
process (an HTTP server on 127.0.0.1 that reads each export and answers 200), or unset. With it,
every relayed message is a receive, a step and a publish span, its context carried in the Zenoh
attachment, exported in batches (the SDK's defaults). Three modes: off, on (every trace recorded)
and sampled (``OTEL_TRACES_SAMPLER=parentbased_traceidratio``, 1 %). In the report the ``raw``
column is telemetry **off**; ``framework`` is **on** (``telemetry_hop``, ``telemetry_throughput``)
or **sampled** (``telemetry_sampled_*``), so each ratio is that mode ÷ off (the issue's target:
≤ 1.05 for the hop). Rounds reverse the order of the modes every other time.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

from . import hop
from .common import Children

__all__ = ["MODES", "SAMPLED_RATIO", "OtlpSink", "run_suite"]

#: off: no endpoint; on: every trace recorded (the default sampler); sampled: 1 trace in 100 recorded.
MODES = ("off", "on", "sampled")
SAMPLED_RATIO = 0.01


class _Handler(BaseHTTPRequestHandler):
    server: _Server

    def log_message(self, format: str, *args: Any) -> None:
        """Quiet."""

    def do_POST(self) -> None:
        length = min(int(self.headers.get("Content-Length") or 0), 64 * 1024 * 1024)
        body = self.rfile.read(length)
        with self.server.lock:
            self.server.exports += 1
            self.server.bytes += len(body)
        self.send_response(200)
        self.send_header("Content-Type", "application/x-protobuf")
        self.send_header("Content-Length", "0")
        self.end_headers()


class _Server(ThreadingHTTPServer):
    daemon_threads = True

    def __init__(self) -> None:
        super().__init__(("127.0.0.1", 0), _Handler)
        self.lock = threading.Lock()
        self.exports = 0
        self.bytes = 0


class OtlpSink:
    """An OTLP/HTTP receiver that counts exports and bytes (and decodes nothing)."""

    def __init__(self) -> None:
        self._server = _Server()
        self._thread = threading.Thread(target=self._server.serve_forever, kwargs={"poll_interval": 0.1},
                                        name="otlp-sink", daemon=True)

    @property
    def endpoint(self) -> str:
        return f"http://127.0.0.1:{self._server.server_address[1]}"

    def counts(self) -> tuple[int, int]:
        """(exports, bytes) received so far."""
        with self._server.lock:
            return self._server.exports, self._server.bytes

    def __enter__(self) -> OtlpSink:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._server.shutdown()
        self._server.server_close()
        self._thread.join(timeout=5)


def run_suite(transports: list[str], settings: dict[str, Any], children: Children, ros_domain: int,
              progress: Callable[[str], None]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """Framework hop pairs with telemetry off (``raw``) and on (``framework``); (records, skipped)."""
    records: list[dict[str, Any]] = []
    skipped: list[dict[str, str]] = []
    if not _otel_installed():
        return records, [{"suite": "telemetry", "transport": "-", "reason": "the otel extra is not installed "
                          "(pip install 'agents-core[otel]')"}]
    rounds = int(settings.get("rounds", 1))
    with OtlpSink() as sink:
        on_env = {"OTEL_EXPORTER_OTLP_ENDPOINT": sink.endpoint, "OTEL_SERVICE_NAME": "bench"}
        environments = {"off": {"OTEL_EXPORTER_OTLP_ENDPOINT": "", "OTEL_EXPORTER_OTLP_TRACES_ENDPOINT": ""},
                        "on": on_env,
                        "sampled": {**on_env, "OTEL_TRACES_SAMPLER": "parentbased_traceidratio",
                                    "OTEL_TRACES_SAMPLER_ARG": str(SAMPLED_RATIO)}}
        for transport in transports:
            for round_no in range(rounds):
                for label in MODES if round_no % 2 == 0 else MODES[::-1]:
                    got: list[dict[str, Any]] = []
                    failure = hop._run_pair(transport, "framework", round_no, settings, children, ros_domain,
                                            lambda line, label=label: progress(f"telemetry {label}: {line}"), got,
                                            extra_env=environments[label])
                    if failure is not None:
                        progress(f"telemetry {transport} {label}: FAILED: {failure.splitlines()[0]}")
                        skipped.append({"suite": "telemetry", "transport": transport, "mode": label,
                                        "reason": failure[-1500:]})
                        continue
                    for record in got:
                        records.extend(_relabelled(record, label))
        exports, size = sink.counts()
        progress(f"telemetry: the receiver got {exports} OTLP exports, {size / 1e6:.2f} MB")
    return records, skipped


def _relabelled(record: dict[str, Any], label: str) -> list[dict[str, Any]]:
    """The record as the report reads it: off is the ``raw`` of both comparisons, on / sampled their ``framework``."""
    base = record["suite"]
    if label == "off":
        return [{**record, "suite": f"telemetry_{base}", "mode": "raw", "telemetry": label},
                {**record, "suite": f"telemetry_sampled_{base}", "mode": "raw", "telemetry": label}]
    suite = f"telemetry_{base}" if label == "on" else f"telemetry_sampled_{base}"
    return [{**record, "suite": suite, "mode": "framework", "telemetry": label}]


def _otel_installed() -> bool:
    import importlib.util  # noqa: PLC0415

    return all(importlib.util.find_spec(name) is not None
               for name in ("opentelemetry.sdk", "opentelemetry.exporter.otlp.proto.http"))
