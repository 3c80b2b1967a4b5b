"""The two ways a received value reaches its callback, and the counters of every subscription.

A transport driver hands each received value to a *sink* (see
:mod:`agents_core.transport.driver`); the core picks the sink when the subscription is opened:

- :class:`BoundedDelivery`, for user callbacks (``create_subscription``): a queue of
  ``topic.qos_profile.depth`` values drained by a thread of its own. When full, the oldest
  waiting value is dropped and counted; neither a slow callback nor a raising one can stall the
  middleware's threads.
- :class:`InlineDelivery`, for component inputs: the callback runs at once on the middleware's
  thread. The core's callback only stores the value and enqueues a step on the component's
  worker (never blocking), so the worker's bounded step queue is the only queue of the hop,
  and a raising callback is counted, never propagated.

Both count every value: each one offered ends delivered, dropped, callback_errors or discarded
(or is still queued), and payloads that do not decode are counted in decode_errors.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Any

from attrs import define

from ..support.concurrency import CloseOnce, DrainQueue
from ..telemetry import switch as _telemetry
from ..topics import Topic

__all__ = ["BoundedDelivery", "InlineDelivery", "SubscriptionStatistics", "TopicCounters", "TopicStatistics",
           "ValidatingSink"]

logger = logging.getLogger(__name__)


@define
class SubscriptionStatistics:
    """Counters for one subscription."""

    delivered: int = 0
    dropped: int = 0
    callback_errors: int = 0
    queued: int = 0
    #: Received payloads that did not decode into the topic's type (networked transports).
    decode_errors: int = 0
    #: Values still waiting when the subscription closed (e.g. on a component's deactivate).
    discarded: int = 0


@define
class TopicStatistics:
    """Counters for one topic in one transport instance, summed over its subscriptions.

    Each value published reaches each local subscription once and there ends delivered,
    dropped, callback_errors or discarded (or is still queued); payloads from the network that
    do not decode are counted in decode_errors.
    """

    published: int = 0
    delivered: int = 0
    dropped: int = 0
    callback_errors: int = 0
    #: Values waiting in a subscription's queue when it closed.
    discarded: int = 0
    #: Received payloads that did not decode (networked transports; always 0 in memory).
    decode_errors: int = 0


class TopicCounters:
    """Per-topic :class:`TopicStatistics` of one transport, what ``Transport.statistics()`` returns.

    Deliveries and publishers add to the live totals (:meth:`live`) under :attr:`lock`, the one
    lock of every counter of the transport: a count costs one uncontended lock, no allocation.
    """

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self._stats: dict[str, TopicStatistics] = {}

    def live(self, topic_name: str) -> TopicStatistics:
        """The live totals of ``topic_name`` (created at zero); change them only under :attr:`lock`."""
        with self.lock:
            stats = self._stats.get(topic_name)
            if stats is None:
                stats = self._stats[topic_name] = TopicStatistics()
            return stats

    track = live

    def snapshot(self, topic_name: str | None = None) -> dict[str, TopicStatistics]:
        """A copy of the counters of every topic, or of ``topic_name`` only."""
        with self.lock:
            return {name: TopicStatistics(s.published, s.delivered, s.dropped, s.callback_errors, s.discarded,
                                          s.decode_errors)
                    for name, s in self._stats.items() if topic_name is None or name == topic_name}


class _Counted:
    """The counters a delivery keeps: its own and, with ``counters``, the topic's totals too."""

    def __init__(self, topic: Topic, counters: TopicCounters | None) -> None:
        self._count_lock = counters.lock if counters is not None else threading.Lock()
        self._stats = SubscriptionStatistics()
        self._totals = counters.live(topic.name) if counters is not None else TopicStatistics()

    def validating(self) -> ValidatingSink:
        """This delivery behind a sink that validates each value first (for a driver that does not)."""
        return ValidatingSink(self.topic, self)  # type: ignore[attr-defined, arg-type]  # a subclass

    def reject(self, reason: object) -> None:
        """Count a received payload that does not decode into the topic's type; never raises.

        Drivers call this instead of ``offer`` when decoding fails. The first rejection is
        logged as a warning with its reason, later ones at debug level, so a stream of bad
        payloads cannot flood the log; all are counted in ``statistics().decode_errors``.
        """
        with self._count_lock:
            self._stats.decode_errors += 1
            self._totals.decode_errors += 1
            first = self._stats.decode_errors == 1
        topic = self.topic  # type: ignore[attr-defined]  # set by the subclasses
        log = logger.warning if first else logger.debug
        log("topic %r: skipped a payload that does not decode as %s: %s%s", topic.name, topic.type_name,
            reason, " (further ones are counted in statistics().decode_errors)" if first else "")

    def _snapshot(self, queued: int) -> SubscriptionStatistics:
        with self._count_lock:
            s = self._stats
            return SubscriptionStatistics(s.delivered, s.dropped, s.callback_errors, queued, s.decode_errors,
                                          s.discarded)


class BoundedDelivery(_Counted):
    """A queue of ``topic.qos_profile.depth`` values drained by one thread into ``callback``.

    With ``counters``, every event is also added to the topic's totals there. Every value
    offered ends in exactly one of delivered, dropped, callback_errors or discarded (or is
    still queued). The queue is a :class:`~agents_core.support.concurrency.DrainQueue` (drop oldest),
    its thread named ``deliver:<topic>``.
    """

    def __init__(self, topic: Topic, callback: Callable[[Any], None], counters: TopicCounters | None = None) -> None:
        super().__init__(topic, counters)
        self.topic = topic
        self._close_once = CloseOnce()
        self._queue = _DeliveryQueue(topic, callback, self._count_lock, self._stats, self._totals)

    def offer(self, value: Any) -> None:
        """Queue ``value`` (never blocks; drops the oldest waiting value when full)."""
        self._queue.put(value)

    def statistics(self) -> SubscriptionStatistics:
        """A snapshot of the counters."""
        return self._snapshot(self._queue.statistics().queued)

    def close(self) -> None:
        """Stop delivering; waiting values are discarded and counted. Idempotent."""
        if not self._close_once.claim():
            return
        self._queue.stop(discard=True)
        self._queue.join(timeout=5.0)


class _DeliveryQueue(DrainQueue[Any]):
    """A :class:`BoundedDelivery`'s queue: it counts its events into the delivery's counters
    (``stats``, kept as ``_counts``) and the topic's totals (``totals``), under ``count_lock``."""

    def __init__(self, topic: Topic, callback: Callable[[Any], None], count_lock: threading.Lock,
                 stats: SubscriptionStatistics, totals: TopicStatistics) -> None:
        self._topic_name = topic.name
        self._count_lock = count_lock
        self._counts = stats
        self._topic_totals = totals
        super().__init__(callback, depth=topic.qos_profile.depth, policy="drop_oldest", name=f"deliver:{topic.name}")

    def _handled(self, item: Any) -> None:
        with self._count_lock:
            self._counts.delivered += 1
            self._topic_totals.delivered += 1

    def _failed(self, item: Any, error: Exception) -> None:
        logger.exception("callback on topic %r raised; the subscription keeps running", self._topic_name)
        with self._count_lock:
            self._counts.callback_errors += 1
            self._topic_totals.callback_errors += 1

    def _dropped(self, count: int) -> None:
        with self._count_lock:
            self._counts.dropped += count
            self._topic_totals.dropped += count

    def _discarded(self, count: int) -> None:
        with self._count_lock:
            self._counts.discarded += count
            self._topic_totals.discarded += count


class InlineDelivery(_Counted):
    """Calls ``callback(value)`` on the thread that offers the value (see the module docstring).

    Same interface and counters as :class:`BoundedDelivery`, without a queue or a thread: the
    callback must return at once.
    """

    def __init__(self, topic: Topic, callback: Callable[[Any], None], counters: TopicCounters | None = None) -> None:
        super().__init__(topic, counters)
        self.topic = topic
        self._callback = callback
        self._closed = False

    def offer(self, value: Any) -> None:
        """Run the callback with ``value`` now; count the outcome; never raises."""
        if self._closed:
            return
        # Counted before the call: the callback hands the value to another thread, which waits
        # for the GIL until this one is done, so nothing should run after it on the way back.
        with self._count_lock:
            self._stats.delivered += 1
            self._totals.delivered += 1
        try:
            tel = _telemetry.hooks
            if tel is None:
                self._callback(value)
            else:  # a receive span, current while the callback queues the step it triggers
                span = tel.receive(self.topic.name)
                try:
                    self._callback(value)
                except BaseException as exc:
                    tel.end(span, exc)
                    raise
                tel.end(span)
        except Exception:
            with self._count_lock:
                self._stats.delivered -= 1
                self._totals.delivered -= 1
                self._stats.callback_errors += 1
                self._totals.callback_errors += 1
                first = self._stats.callback_errors == 1
            (logger.exception if first else logger.debug)(
                "callback on topic %r raised; the subscription keeps running", self.topic.name)

    def statistics(self) -> SubscriptionStatistics:
        """A snapshot of the counters (``queued`` is always 0)."""
        return self._snapshot(0)

    def close(self) -> None:
        """Stop calling back; idempotent."""
        self._closed = True


class ValidatingSink:
    """A sink that validates each value against the topic's type before offering it to ``sink``.

    What the core gives a driver that does not declare ``validates_incoming`` (see
    :meth:`agents_core.transport.driver.Sink.offer`): a value that does not validate is rejected,
    with why, and counted as a decode error. Never blocks, never raises.
    """

    def __init__(self, topic: Topic, sink: BoundedDelivery | InlineDelivery) -> None:
        self._validate = topic.msg_type.validate
        self._sink = sink

    def offer(self, value: Any) -> None:
        """Validate ``value``, then offer its canonical form (or reject it)."""
        try:
            checked = self._validate(value)
        except Exception as exc:  # a driver's value must never raise into the driver's thread
            self._sink.reject(exc)
            return
        self._sink.offer(checked)

    def reject(self, reason: object) -> None:
        """A payload that did not decode: passed on."""
        self._sink.reject(reason)

