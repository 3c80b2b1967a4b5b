"""Spans recorded at a few µs each: the hot-path half of the telemetry (no OpenTelemetry import here).

The OpenTelemetry SDK's tracer costs tens of µs per span in CPython (measured: ~50 µs sampled,
~20 µs not, on the 2-core CI machine), more than a whole Zenoh hop. Here a span is a small object
with ``__slots__``: ids from :func:`random.getrandbits`, the current span in a
:class:`contextvars.ContextVar`, and, when the trace is sampled, the finished span appended to a
bounded deque (full: the oldest are dropped and counted). :mod:`agents_core.telemetry.otel` turns
the finished spans into OpenTelemetry's ``ReadableSpan`` and exports them from a thread of its own.

Sampling follows ``OTEL_TRACES_SAMPLER`` / ``OTEL_TRACES_SAMPLER_ARG`` (``always_on``, the default,
``always_off``, ``traceidratio`` and their ``parentbased_`` forms; a span with a parent always
follows its parent's decision) or :attr:`TelemetrySettings.sample_ratio`. A trace that is not
sampled still carries its context (flags ``00``), so the next process does not sample it either,
and costs no span objects at all.
"""

from __future__ import annotations

import collections
import contextvars
import os
import random
import threading
import time
from typing import Any

__all__ = [
    "CLIENT",
    "CONSUMER",
    "INTERNAL",
    "PRODUCER",
    "FinishedSpan",
    "SpanRecorder",
    "parse_traceparent",
    "sampling_ratio",
]

INTERNAL, CLIENT, PRODUCER, CONSUMER = 0, 2, 3, 4  # OpenTelemetry's SpanKind values
_getrandbits = random.getrandbits
_time_ns = time.time_ns
_HEX = frozenset("0123456789abcdef")

#: (trace id, span id, sampled, from another process, its traceparent or None): the current span's
#: context, None outside any trace. A trace that is not sampled keeps the header it came with.
Context = tuple[int, int, bool, bool, str | None]


def parse_traceparent(header: str | None) -> Context | None:
    """The context of a W3C ``traceparent`` header; None when malformed (or all-zero ids)."""
    if not header or len(header) != 55 or header[:3] != "00-" or header[35] != "-" or header[52] != "-" \
            or not _HEX.issuperset(header[3:35] + header[36:52] + header[53:]):
        return None
    if header[3:35] == "0" * 32 or header[36:52] == "0" * 16:
        return None
    if not int(header[53:], 16) & 1:  # not sampled: nothing is recorded under it, the header goes on as it is
        return 0, 0, False, True, header
    return int(header[3:35], 16), int(header[36:52], 16), True, True, None


def sampling_ratio(ratio: float | None = None) -> float:
    """The share of new traces to sample: ``ratio`` if given, else what ``OTEL_TRACES_SAMPLER`` says."""
    if ratio is not None:
        return min(1.0, max(0.0, float(ratio)))
    sampler = os.environ.get("OTEL_TRACES_SAMPLER", "parentbased_always_on").strip().lower()
    if sampler.endswith("always_off"):
        return 0.0
    if sampler.endswith("traceidratio"):
        try:
            return min(1.0, max(0.0, float(os.environ.get("OTEL_TRACES_SAMPLER_ARG", "1.0"))))
        except ValueError:
            return 1.0
    return 1.0


class FinishedSpan:
    """One ended, sampled span, as the exporter reads it."""

    __slots__ = ("attributes", "end_ns", "error", "kind", "name", "parent_id", "remote_parent", "span_id",
                 "start_ns", "trace_id")

    def __init__(self, name: str, kind: int, trace_id: int, span_id: int, parent_id: int, remote_parent: bool,
                 start_ns: int, attributes: dict[str, Any]) -> None:
        self.name = name
        self.kind = kind
        self.trace_id = trace_id
        self.span_id = span_id
        self.parent_id = parent_id
        self.remote_parent = remote_parent
        self.start_ns = start_ns
        self.end_ns = start_ns
        self.attributes = attributes
        self.error: str | None = None


class _Span:
    """A span while it runs: current in its context, recorded when it ends (if sampled)."""

    __slots__ = ("_attributes", "_context", "_kind", "_name", "_parent", "_recorder", "_span", "_token")

    def __init__(self, recorder: SpanRecorder, name: str, kind: int, attributes: dict[str, Any],
                 parent: Context | None) -> None:
        self._recorder = recorder
        self._name = name
        self._kind = kind
        self._attributes = attributes
        self._parent = parent
        self._span: FinishedSpan | None = None
        self._token: Any = None

    def __enter__(self) -> _Span:
        recorder = self._recorder
        parent = self._parent
        if parent is None:  # a new trace: the sampling decision is made here
            trace_id = _getrandbits(128) or 1
            sampled = recorder.ratio >= 1.0 or (trace_id & 0xFFFFFFFFFFFFFFFF) < recorder.bound
            parent_id, remote = 0, False
        else:
            trace_id, parent_id, sampled, remote, _ = parent
        span_id = _getrandbits(64) or 1
        if sampled:
            self._span = FinishedSpan(self._name, self._kind, trace_id, span_id, parent_id, remote, _time_ns(),
                                      self._attributes)
            self._token = recorder.current.set((trace_id, span_id, True, False, None))
        else:  # a new trace that is not recorded: its context still goes on (flags 00)
            self._token = recorder.current.set((0, 0, False, False, f"00-{trace_id:032x}-{span_id:016x}-00"))
        return self

    def set_attribute(self, key: str, value: Any) -> None:
        """Add an attribute (nothing when the span is not sampled)."""
        if self._span is not None:
            self._span.attributes[key] = value

    def __exit__(self, kind: Any, exc: Any, tb: Any) -> None:
        span = self._span
        if span is not None:
            span.end_ns = _time_ns()
            if exc is not None:
                span.error = f"{type(exc).__name__}: {exc}"[:500]
            self._recorder.finish(span)
        if self._token is not None:
            self._recorder.current.reset(self._token)


class _NoSpan:
    """A span under a parent that is not sampled: nothing to record, the context stays the parent's."""

    __slots__ = ()

    def __enter__(self) -> _NoSpan:
        return self

    def set_attribute(self, key: str, value: Any) -> None:
        """Nothing (not recorded)."""

    def __exit__(self, kind: Any, exc: Any, tb: Any) -> None:
        return None


_NO_SPAN = _NoSpan()


class SpanRecorder:
    """Makes the spans of one process and keeps the finished, sampled ones for the exporter."""

    def __init__(self, ratio: float = 1.0, max_queue: int = 8192) -> None:
        self.ratio = ratio
        self.bound = int(ratio * 2**64)
        self.current: contextvars.ContextVar[Context | None] = contextvars.ContextVar("agents_span", default=None)
        self._finished: collections.deque[FinishedSpan] = collections.deque()
        self._max_queue = max_queue
        self.dropped = 0
        self._lock = threading.Lock()
        self.ready = threading.Event()
        self.batch_size = 512

    def span(self, name: str, kind: int = INTERNAL, attributes: dict[str, Any] | None = None,
             parent: Context | bool | None = True) -> _Span | _NoSpan:
        """A span (a context manager); ``parent``: True for the current span, a context, or None for a new trace.

        ``attributes`` may be shared between spans: only a model call's span adds to its own copy.
        """
        context = self.current.get() if parent is True else parent
        if context and not context[2]:
            return _NO_SPAN
        return _Span(self, name, kind, attributes if attributes is not None else {}, context or None)

    def enter(self, context: Context) -> contextvars.Token[Context | None]:
        """Make a received context current (undo with :meth:`leave`)."""
        return self.current.set(context)

    def leave(self, token: contextvars.Token[Context | None]) -> None:
        """Undo :meth:`enter`."""
        self.current.reset(token)

    def traceparent(self) -> str | None:
        """The current context as a W3C ``traceparent`` (None outside any trace)."""
        context = self.current.get()
        if context is None:
            return None
        return context[4] or f"00-{context[0]:032x}-{context[1]:016x}-01"

    def finish(self, span: FinishedSpan) -> None:
        """Keep an ended span for the exporter (the oldest dropped, counted, when the queue is full)."""
        with self._lock:
            if len(self._finished) >= self._max_queue:
                self._finished.popleft()
                self.dropped += 1
            self._finished.append(span)
            if len(self._finished) == self.batch_size:  # a full batch: the exporter need not wait its delay
                self.ready.set()

    def drain(self, limit: int) -> list[FinishedSpan]:
        """Up to ``limit`` finished spans, oldest first, removed from the queue."""
        with self._lock:
            count = min(limit, len(self._finished))
            return [self._finished.popleft() for _ in range(count)]

    def pending(self) -> int:
        """How many finished spans wait for the exporter."""
        with self._lock:
            return len(self._finished)
