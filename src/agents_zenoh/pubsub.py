"""Publishers and subscribers of the Zenoh driver: QoS mapping, encoding, decoding into the core's sink."""

from __future__ import annotations

import struct
import threading
import time
from typing import Any

import zenoh

from agents_core.errors import TransportClosedError, TransportError
from agents_core.telemetry import switch as _telemetry
from agents_core.telemetry.carrier import append_traceparent, traceparent_of
from agents_core.topics import Topic
from agents_core.transport.driver import Sink

from .codecs import MSGPACK, CodecError, decoder_for, encoder_for
from .context import ZenohContext, undeclare
from .graph import EntityToken
from .shm import shm_payload

__all__ = ["ZenohPublisher", "ZenohSubscription"]

# The attachment of every sample, the msgpack map {"seq": n, "stamp_ns": t}, written with one
# struct call: both numbers as msgpack uint64 (0xcf), which any msgpack reader decodes to the
# same ints as msgpack.packb's shortest form (a dict and a packb call per sample cost more).
_ATTACHMENT = struct.Struct(">B4sBQ9sBQ")
_SEQ_KEY, _STAMP_KEY = b"\xa3seq", b"\xa8stamp_ns"


_PACK_ATTACHMENT = _ATTACHMENT.pack


def _attachment(seq: int, stamp_ns: int) -> bytes:
    return _PACK_ATTACHMENT(0x82, _SEQ_KEY, 0xCF, seq, _STAMP_KEY, 0xCF, stamp_ns)


_PUT = zenoh.SampleKind.PUT


class ZenohPublisher:
    """Puts one topic's values on ``<namespace>/<topic>`` (see :mod:`agents_zenoh.transport`)."""

    def __init__(self, context: ZenohContext, topic: Topic) -> None:
        self.topic = topic
        self._context = context
        self._lock = threading.Lock()
        self._seq = 0
        self._closed = False
        self._buffer = bytearray()
        self._encode = encoder_for(topic.msg_type)
        qos = topic.qos_profile
        reliable = qos.reliability == "reliable"
        options: dict[str, Any] = {
            "encoding": zenoh.Encoding(MSGPACK).with_schema(topic.type_name),
            "congestion_control": zenoh.CongestionControl.BLOCK if reliable else zenoh.CongestionControl.DROP,
            "reliability": zenoh.Reliability.RELIABLE if reliable else zenoh.Reliability.BEST_EFFORT,
            "priority": context.priority(topic),
        }
        key = context.key(topic.name)
        self._pub: zenoh.Publisher | zenoh.ext.AdvancedPublisher
        if qos.durability == "transient_local":
            self._pub = zenoh.ext.declare_advanced_publisher(
                context.session, key, cache=zenoh.ext.CacheConfig(qos.depth), publisher_detection=True,
                **options)
            # Late joiners fetch the cache, so there is no discovery race to wait out.
            self._match_deadline = 0.0
        else:
            self._pub = context.session.declare_publisher(key, **options)
            self._match_deadline = time.monotonic() + context.match_timeout
        # Bound once: send() runs for every value.
        self._put = self._pub.put
        self._shm = shm_payload(context.shm)  # large payloads from shared memory (agents_zenoh.shm)
        # For graph discovery (agents_zenoh.graph): who publishes what, seen by any peer.
        self._token = EntityToken(context, "pub", topic)

    def send(self, value: Any) -> None:
        """Encode and put ``value`` (validated by the core)."""
        if self._closed:
            raise TransportClosedError(f"publisher on {self.topic.name!r} is closed")
        if self._match_deadline:
            self._wait_for_match()
        with self._lock:
            # Under the lock: the reusable buffer is shared, and sequence numbers follow put order.
            payload: Any = self._encode(value, self._buffer)
            seq = self._seq
            self._seq = seq + 1
            attachment = _PACK_ATTACHMENT(0x82, _SEQ_KEY, 0xCF, seq, _STAMP_KEY, 0xCF, time.time_ns())
            tel = _telemetry.hooks
            if tel is not None and (traceparent := tel.traceparent()) is not None:
                attachment = append_traceparent(attachment, traceparent)  # the W3C context of the publish span
            if len(payload) >= self._shm[0]:
                payload = self._shm[1](payload)
            try:
                self._put(payload, attachment=attachment)
            except zenoh.ZError as exc:
                self._context.check_open(f"publish on {self.topic.name!r}")
                raise TransportError(f"publishing on {self.topic.name!r} failed: {exc}") from exc

    def _wait_for_match(self) -> None:
        # A Zenoh publisher learns about subscribers asynchronously; a value put before that
        # is lost. Right after creation, wait (bounded) for the first match instead.
        if not self._match_deadline:
            return
        while time.monotonic() < self._match_deadline:
            # zenoh-python 1.x returns a MatchingStatus object here (its stub says bool).
            status: Any = getattr(self._pub, "matching_status", True)
            if getattr(status, "matching", status):
                break
            time.sleep(0.001)
        self._match_deadline = 0.0

    def close(self) -> None:
        """Undeclare the publisher; idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self._token.close()
        undeclare(self._pub)


class ZenohSubscription:
    """Decodes one topic's samples into the core's sink, on Zenoh's thread (see :mod:`agents_zenoh.transport`)."""

    def __init__(self, context: ZenohContext, topic: Topic, sink: Sink) -> None:
        self.topic = topic
        self._closed = False
        self._schema = topic.type_name
        # What this topic's publishers send: a sample that carries it is checked with one
        # comparison (anything else takes the full check in _check_encoding).
        self._encoding = zenoh.Encoding(MSGPACK).with_schema(topic.type_name)
        self._delivery = sink
        self._decode = decoder_for(topic.msg_type)
        key = context.key(topic.name)
        self._sub: zenoh.Subscriber[None] | zenoh.ext.AdvancedSubscriber[None]
        if topic.qos_profile.durability == "transient_local":
            history = zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=topic.qos_profile.depth)
            self._sub = zenoh.ext.declare_advanced_subscriber(context.session, key, self._on_sample,
                                                              history=history)
        else:
            self._sub = context.session.declare_subscriber(key, self._on_sample)
        self._token = EntityToken(context, "sub", topic)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        # Runs on a Zenoh thread: it must never raise, and never block for long.
        if self._closed or sample.kind != _PUT:
            return
        try:
            encoding = sample.encoding
            if encoding != self._encoding:
                self._check_encoding(str(encoding))
            value = self._decode(sample.payload.to_bytes())
        except Exception as exc:
            self._delivery.reject(exc)
            return
        tel = _telemetry.hooks
        if tel is None:
            self._delivery.offer(value)
            return
        attachment = sample.attachment  # the sender's trace context, if it sent one
        token = tel.enter_remote(traceparent_of(attachment.to_bytes() if attachment is not None else None))
        try:
            self._delivery.offer(value)
        finally:
            tel.leave(token)

    def _check_encoding(self, encoding: str) -> None:
        base, _, schema = encoding.partition(";")
        if base != MSGPACK:
            raise CodecError(f"cannot decode the sample as {self._schema}: its encoding is {encoding!r}, "
                             f"not {MSGPACK!r}")
        if schema and schema != self._schema:
            raise CodecError(f"cannot decode the sample as {self._schema}: it carries type {schema!r}")

    def close(self) -> None:
        """Undeclare the subscriber; idempotent."""
        if self._closed:
            return
        self._closed = True
        self._token.close()
        undeclare(self._sub)

