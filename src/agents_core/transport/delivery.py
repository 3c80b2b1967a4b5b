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

import collections
import logging
import threading
from collections.abc import Callable
from typing import Any

from attrs import define

from ..topics import Topic

__all__ = ["BoundedDelivery", "InlineDelivery", "SubscriptionStatistics", "TopicCounters", "TopicStatistics"]

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
    """Thread-safe per-topic :class:`TopicStatistics`, what ``Transport.statistics()`` returns."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._stats: dict[str, TopicStatistics] = {}

    def track(self, topic_name: str) -> None:
        """Make ``topic_name`` appear in snapshots (with zero counts) from now on."""
        with self._lock:
            self._stats.setdefault(topic_name, TopicStatistics())

    def count(self, topic_name: str, **counts: int) -> None:
        """Add ``counts`` (field name -> increment) to the topic's counters."""
        with self._lock:
            stats = self._stats.setdefault(topic_name, TopicStatistics())
            for name, n in counts.items():
                setattr(stats, name, getattr(stats, name) + n)

    def snapshot(self, topic_name: str | None = None) -> dict[str, TopicStatistics]:
        """A copy of the counters of every topic, or of ``topic_name`` only."""
        with self._lock:
            return {name: TopicStatistics(s.published, s.delivered, s.dropped, s.callback_errors, s.discarded,
                                          s.decode_errors)
                    for name, s in self._stats.items() if topic_name is None or name == topic_name}


class BoundedDelivery:
    """A queue of ``topic.qos_profile.depth`` values drained by one thread into ``callback``.

    ``on_count(delivered=, dropped=, callback_errors=, discarded=)`` is told about every event,
    for transport-wide statistics. Every value offered ends in exactly one of delivered,
    dropped, callback_errors or discarded (or is still queued).
    """

    def __init__(self, topic: Topic, callback: Callable[[Any], None],
                 on_count: Callable[..., None] | None = None) -> None:
        self.topic = topic
        self._callback = callback
        self._on_count = on_count
        self._queue: collections.deque[Any] = collections.deque()
        self._depth = topic.qos_profile.depth
        self._cond = threading.Condition()
        self._closed = False
        self._stats = SubscriptionStatistics()
        self._thread = threading.Thread(target=self._run, name=f"deliver:{topic.name}", daemon=True)
        self._thread.start()

    def offer(self, value: Any) -> None:
        """Queue ``value`` (never blocks; drops the oldest waiting value when full)."""
        dropped = False
        with self._cond:
            if self._closed:
                return
            if len(self._queue) >= self._depth:
                self._queue.popleft()
                self._stats.dropped += 1
                dropped = True
            self._queue.append(value)
            self._cond.notify()
        if dropped and self._on_count is not None:
            self._on_count(dropped=1)

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._queue and not self._closed:
                    self._cond.wait()
                if self._closed:
                    return
                value = self._queue.popleft()
            try:
                self._callback(value)
            except Exception:
                logger.exception("callback on topic %r raised; the subscription keeps running", self.topic.name)
                with self._cond:
                    self._stats.callback_errors += 1
                if self._on_count is not None:
                    self._on_count(callback_errors=1)
            else:
                with self._cond:
                    self._stats.delivered += 1
                if self._on_count is not None:
                    self._on_count(delivered=1)

    def reject(self, reason: object) -> None:
        """Count a received payload that does not decode into the topic's type; never raises.

        Adapters call this instead of :meth:`offer` when decoding fails. The first rejection is
        logged as a warning with its reason, later ones at debug level, so a stream of bad
        payloads cannot flood the log; all are counted in ``statistics().decode_errors``.
        """
        with self._cond:
            self._stats.decode_errors += 1
            first = self._stats.decode_errors == 1
        if self._on_count is not None:
            self._on_count(decode_errors=1)
        log = logger.warning if first else logger.debug
        log("topic %r: skipped a payload that does not decode as %s: %s%s", self.topic.name, self.topic.type_name,
            reason, " (further ones are counted in statistics().decode_errors)" if first else "")

    def statistics(self) -> SubscriptionStatistics:
        """A snapshot of the counters."""
        with self._cond:
            s = self._stats
            return SubscriptionStatistics(s.delivered, s.dropped, s.callback_errors, len(self._queue),
                                          s.decode_errors, s.discarded)

    def close(self) -> None:
        """Stop delivering; waiting values are discarded and counted. Idempotent."""
        with self._cond:
            if self._closed:
                return
            self._closed = True
            discarded = len(self._queue)
            self._stats.discarded += discarded
            self._queue.clear()
            self._cond.notify_all()
        if discarded and self._on_count is not None:
            self._on_count(discarded=discarded)
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout=5.0)


class InlineDelivery:
    """Calls ``callback(value)`` on the thread that offers the value (see the module docstring).

    Same interface and counters as :class:`BoundedDelivery`, without a queue or a thread: the
    callback must return at once.
    """

    def __init__(self, topic: Topic, callback: Callable[[Any], None],
                 on_count: Callable[..., None] | None = None) -> None:
        self.topic = topic
        self._callback = callback
        self._on_count = on_count
        self._lock = threading.Lock()
        self._closed = False
        self._stats = SubscriptionStatistics()

    def offer(self, value: Any) -> None:
        """Run the callback with ``value`` now; count the outcome; never raises."""
        if self._closed:
            return
        try:
            self._callback(value)
        except Exception:
            with self._lock:
                self._stats.callback_errors += 1
                first = self._stats.callback_errors == 1
            (logger.exception if first else logger.debug)(
                "callback on topic %r raised; the subscription keeps running", self.topic.name)
            if self._on_count is not None:
                self._on_count(callback_errors=1)
            return
        with self._lock:
            self._stats.delivered += 1
        if self._on_count is not None:
            self._on_count(delivered=1)

    def reject(self, reason: object) -> None:
        """Count a payload that does not decode (logged once, as :meth:`BoundedDelivery.reject`)."""
        with self._lock:
            self._stats.decode_errors += 1
            first = self._stats.decode_errors == 1
        if self._on_count is not None:
            self._on_count(decode_errors=1)
        log = logger.warning if first else logger.debug
        log("topic %r: skipped a payload that does not decode as %s: %s%s", self.topic.name, self.topic.type_name,
            reason, " (further ones are counted in statistics().decode_errors)" if first else "")

    def statistics(self) -> SubscriptionStatistics:
        """A snapshot of the counters (``queued`` is always 0)."""
        with self._lock:
            s = self._stats
            return SubscriptionStatistics(s.delivered, s.dropped, s.callback_errors, 0, s.decode_errors, s.discarded)

    def close(self) -> None:
        """Stop calling back; idempotent."""
        self._closed = True
