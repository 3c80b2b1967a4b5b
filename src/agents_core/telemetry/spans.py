"""Spans recorded at well under a µs each: the hot-path half of the telemetry (no OpenTelemetry import here).

The OpenTelemetry SDK's tracer costs tens of µs per span in CPython (measured: ~50 µs sampled,
~20 µs not, on the 2-core CI machine), more than a whole in-process hop. Here a span is a tuple:

- :meth:`SpanRecorder.begin` makes the open span (its context first: trace id, span id, sampled,
  from another process, the context to restore) and makes it current on this thread, a
  :class:`threading.local` attribute (no :mod:`contextvars` token); :meth:`SpanRecorder.end` puts
  the previous context back and appends ``(open span, end time, error)`` to a deque. Two plain
  calls, one clock reading each, no lock (a deque's append is atomic), no dict copied: a span's
  attributes are kept by reference (the per-topic ones are shared, never changed).
- span ids count up from a random per-process base (:func:`itertools.count`, atomic); a trace id
  is 128 random bits, made once per trace;
- everything else (ids as OTLP bytes, ``ReadableSpan``, protobuf, HTTP) happens on the exporter's
  thread (:mod:`agents_core.telemetry.otel`). The deque is bounded: full, the oldest finished span
  is dropped and counted.

A context crosses threads as a value: :meth:`SpanRecorder.capture` on the sending thread,
``parent=`` of :meth:`SpanRecorder.begin` on the receiving one.

Sampling follows ``OTEL_TRACES_SAMPLER`` / ``OTEL_TRACES_SAMPLER_ARG`` (``always_on``, the default,
``always_off``, ``traceidratio`` and their ``parentbased_`` forms; a span with a parent always
follows its parent's decision) or :attr:`TelemetrySettings.sample_ratio`. A trace that is not
sampled still carries its context (flags ``00``), so the next process does not sample it either,
and records nothing: under it a span is no object at all (``None``).
"""

from __future__ import annotations

import collections
import itertools
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
    "Context",
    "FinishedSpan",
    "SpanRecorder",
    "parse_traceparent",
    "sampling_ratio",
]

INTERNAL, CLIENT, PRODUCER, CONSUMER = 0, 2, 3, 4  # OpenTelemetry's SpanKind values
_getrandbits = random.getrandbits
_time_ns = time.time_ns
_HEX = frozenset("0123456789abcdef")
_MASK64 = (1 << 64) - 1

#: A context (the current span's, or one received): a tuple whose first five entries are
#: (trace id, span id, sampled, from another process, the context to restore when it ends);
#: an open sampled span goes on with (name, kind, parent span id, parent from another process,
#: start time in ns, attributes). None outside any trace.
Context = tuple[Any, ...]
TRACE, SPAN, SAMPLED, REMOTE, PREVIOUS, NAME, KIND, PARENT, PARENT_REMOTE, START, ATTRIBUTES = range(11)

#: One ended span as the exporter reads it: (the open span, end time in ns, error text or None).
FinishedSpan = tuple[Context, int, str | None]


def parse_traceparent(header: str | None) -> Context | None:
    """The context of a W3C ``traceparent`` header; None when malformed (or all-zero ids)."""
    if not header or len(header) != 55 or header[:3] != "00-" or header[35] != "-" or header[52] != "-" \
            or not _HEX.issuperset(header[3:35] + header[36:52] + header[53:]):
        return None
    trace_id, span_id = int(header[3:35], 16), int(header[36:52], 16)
    if not trace_id or not span_id:
        return None
    return trace_id, span_id, bool(int(header[53:], 16) & 1), True, None


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


class _Current(threading.local):
    context: Context | None = None  # a class attribute: every thread starts outside any trace


class SpanRecorder:
    """Makes the spans of one process and keeps the finished, sampled ones for the exporter."""

    def __init__(self, ratio: float = 1.0, max_queue: int = 8192) -> None:
        self.ratio = ratio
        self.bound = int(ratio * 2**64)
        self._always = ratio >= 1.0
        self.current = _Current()
        # Span ids: a random base (below 2**63, so that counting up never wraps) plus a counter.
        self._ids = itertools.count(_getrandbits(63) | 1)
        self._finished: collections.deque[FinishedSpan] = collections.deque()
        self._max_queue = max_queue
        self.dropped = 0
        self._lock = threading.Lock()  # the dropped count and the consumers; never taken per span
        self.ready = threading.Event()
        self.batch_size = 512

    # -- the hot path ----------------------------------------------------------------------------

    def begin(self, name: str, kind: int, attributes: dict[str, Any], parent: Any = True) -> Context | None:
        """Open a span, current on this thread until :meth:`end`; ``parent``: True for the current span,
        else a context (from :meth:`capture`) or None for a new trace.

        Returns the open span, or None when nothing was made current (under a trace not sampled,
        where the current context already is that trace's); :meth:`end` takes either.
        """
        current = self.current
        previous = current.context
        context: Context | None = previous if parent is True else parent
        opened: Context
        if context is None:  # a new trace: the sampling decision is made here
            trace_id = _getrandbits(128) or 1
            if not (self._always or (trace_id & _MASK64) < self.bound):  # its context still goes on (flags 00)
                current.context = opened = (trace_id, next(self._ids), False, False, previous)
                return opened
            parent_id, parent_remote = 0, False
        elif context[SAMPLED]:
            trace_id, parent_id, parent_remote = context[TRACE], context[SPAN], context[REMOTE]
        elif context is previous:
            return None
        else:  # a context not sampled from another thread: current here too, until the end
            current.context = opened = (context[TRACE], context[SPAN], False, context[REMOTE], previous)
            return opened
        current.context = opened = (trace_id, next(self._ids), True, False, previous, name, kind, parent_id,
                                    parent_remote, _time_ns(), attributes)
        return opened

    def end(self, span: Context | None, error: BaseException | None = None) -> None:
        """End a span :meth:`begin` opened: the previous context is current again, the span recorded."""
        if span is None:
            return
        self.current.context = span[PREVIOUS]
        if not span[SAMPLED]:
            return
        finished = self._finished
        count = len(finished)
        if count >= self._max_queue or error is not None:
            self.finish(span, error)
            return
        finished.append((span, _time_ns(), None))  # finish() inlined: this runs for every message
        if count + 1 == self.batch_size:  # a full batch: the exporter need not wait its delay
            self.ready.set()

    def detach(self, span: Context | None) -> None:
        """Make the context before ``span`` current again, ``span`` left open (to :meth:`finish` later)."""
        if span is not None and self.current.context is span:
            self.current.context = span[PREVIOUS]

    def finish(self, span: Context | None, error: BaseException | None = None) -> None:
        """Record an open sampled span as ended now (the current context is not touched)."""
        if span is None or not span[SAMPLED]:
            return
        text = None if error is None else f"{type(error).__name__}: {error}"[:500]
        finished = self._finished
        if len(finished) >= self._max_queue:
            with self._lock:  # the oldest dropped, counted
                if finished:
                    finished.popleft()
                self.dropped += 1
        finished.append((span, _time_ns(), text))
        if len(finished) == self.batch_size:  # a full batch: the exporter need not wait its delay
            self.ready.set()

    def capture(self) -> Context | None:
        """The current context, to hand to another thread (``parent=`` of :meth:`begin` there)."""
        return self.current.context

    def enter(self, context: Context | None) -> Context | None:
        """Make a received context current (None: outside any trace); what to :meth:`leave` with."""
        current = self.current
        previous = current.context
        current.context = context
        return previous

    def leave(self, previous: Context | None) -> None:
        """Undo :meth:`enter` (``previous``: what it returned)."""
        self.current.context = previous

    def traceparent(self) -> str | None:
        """The current context as a W3C ``traceparent`` (None outside any trace)."""
        context = self.current.context
        if context is None:
            return None
        return f"00-{context[TRACE]:032x}-{context[SPAN] & _MASK64:016x}-{'01' if context[SAMPLED] else '00'}"

    # -- a span as a context manager, for the paths that are not per message -----------------------

    def span(self, name: str, kind: int = INTERNAL, attributes: dict[str, Any] | None = None,
             parent: Context | bool | None = True) -> Span:
        """A span as a context manager (:meth:`begin` and :meth:`end`), with ``set_attribute``."""
        return Span(self, name, kind, {} if attributes is None else attributes, parent)

    # -- the exporter's side -----------------------------------------------------------------------

    def drain(self, limit: int) -> list[FinishedSpan]:
        """Up to ``limit`` finished spans, oldest first, removed from the queue."""
        finished = self._finished
        with self._lock:
            count = min(limit, len(finished))
            return [finished.popleft() for _ in range(count)]

    def pending(self) -> int:
        """How many finished spans wait for the exporter."""
        return len(self._finished)


class Span:
    """:meth:`SpanRecorder.span`: current while the ``with`` block runs; an exception sets its error."""

    __slots__ = ("_args", "_open", "_recorder")

    def __init__(self, recorder: SpanRecorder, name: str, kind: int, attributes: dict[str, Any],
                 parent: Context | bool | None) -> None:
        self._recorder = recorder
        self._args = (name, kind, attributes, parent)
        self._open: Context | None = None

    def __enter__(self) -> Span:
        self._open = self._recorder.begin(*self._args)
        return self

    @property
    def open_span(self) -> Context | None:
        """The open span (None when not recorded)."""
        return self._open

    def set_attribute(self, key: str, value: Any) -> None:
        """Add an attribute (nothing when the span is not sampled)."""
        span = self._open
        if span is not None and span[SAMPLED]:
            span[ATTRIBUTES][key] = value

    def __exit__(self, kind: Any, exc: Any, tb: Any) -> None:
        self._recorder.end(self._open, exc)
