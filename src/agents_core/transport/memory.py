"""The in-memory transport: one process, no encoding, bounded queues, statistics.

This is what unit tests (the framework's and users') run on. Each :class:`MemoryTransport` is
independent (no global state), thread-safe, and delivers the publisher's value object itself
to every subscriber (zero-copy: treat received values as read-only).

Queue policy: each subscription has its own queue of ``topic.qos_profile.depth`` values and its
own delivery thread, so a slow subscriber never blocks a publisher or another subscriber. When
its queue is full the **oldest** queued value is dropped and counted
(:attr:`SubscriptionStatistics.dropped`, and per topic in :meth:`MemoryTransport.statistics`).
With ``durability="transient_local"`` the last ``depth`` values of a topic are replayed to a
subscriber that joins late.
"""

from __future__ import annotations

import collections
import threading
import time
from concurrent.futures import Future, wait
from typing import TYPE_CHECKING, Any

from attrs import define

from ..errors import (
    RemoteError,
    RequestTimeoutError,
    ServiceUnavailableError,
    TransportClosedError,
    WiringError,
)
from ..messages import ComponentStatusMsg
from ..status import HealthStatus, LifecycleState
from ..topics import Topic, validate_topic_name
from .contract import (
    ServiceHandler,
    SubscriptionCallback,
    TransitionHandler,
    Transport,
    TransportCapabilities,
)
from .delivery import BoundedDelivery, SubscriptionStatistics, TopicStatistics
from .requests import RequestLanes, check_timeout, serve_with_caller_deadline, with_caller_timeout

__all__ = ["MemoryTransport", "SubscriptionStatistics", "TopicStatistics"]


class _MemoryPublisher:
    def __init__(self, transport: MemoryTransport, topic: Topic) -> None:
        self.topic = topic
        self._transport = transport
        self._closed = False

    def publish(self, value: Any) -> None:
        if self._closed:
            raise TransportClosedError(f"publisher on {self.topic.name!r} is closed")
        self._transport._deliver(self.topic, self.topic.msg_type.validate(value))

    def close(self) -> None:
        self._closed = True


class _MemorySubscription:
    def __init__(self, transport: MemoryTransport, topic: Topic, callback: SubscriptionCallback) -> None:
        self.topic = topic
        self._transport = transport
        self._delivery = BoundedDelivery(topic, callback,
                                         lambda **counts: transport._count(topic.name, **counts))

    def _offer(self, value: Any) -> None:
        self._delivery.offer(value)

    def statistics(self) -> SubscriptionStatistics:
        """A snapshot of this subscription's counters."""
        return self._delivery.statistics()

    def close(self) -> None:
        self._transport._remove_subscription(self)
        self._delivery.close()


class _MemoryService:
    def __init__(self, transport: MemoryTransport, name: str) -> None:
        self.name = name
        self._transport = transport

    def close(self) -> None:
        self._transport._remove_service(self.name)


@define
class _MemoryPresence:
    name: str
    on_transition: TransitionHandler
    transport: MemoryTransport
    state: LifecycleState = LifecycleState.UNCONFIGURED
    health: HealthStatus = HealthStatus.HEALTHY
    message: str = ""

    def update(self, state: LifecycleState, health: HealthStatus, message: str = "") -> None:
        self.state, self.health, self.message = state, health, message

    def close(self) -> None:
        self.transport._remove_component(self.name)


class MemoryTransport:
    """In-process transport for tests and single-process robots.

    ``request_workers`` bounds how many requests for services without an owner run at once;
    each component's requests run on a lane of their own (see
    :mod:`agents_core.transport.requests`).
    """

    name = "memory"
    capabilities = TransportCapabilities(cross_process=False, services=True, actions=False,
                                         shared_memory=False, zero_copy=True, lifecycle_services=True)

    def __init__(self, *, request_workers: int = 4) -> None:
        self._lock = threading.RLock()
        self._subscriptions: dict[str, list[_MemorySubscription]] = {}
        self._types: dict[str, str] = {}
        self._latched: dict[str, collections.deque[Any]] = {}
        self._stats: dict[str, TopicStatistics] = {}
        self._services: dict[str, tuple[ServiceHandler, str | None]] = {}
        self._components: dict[str, _MemoryPresence] = {}
        self._lanes = RequestLanes("memory-request", shared_workers=request_workers)
        self._closed = False

    # -- pub/sub --------------------------------------------------------------------------

    def _check_open(self) -> None:
        if self._closed:
            raise TransportClosedError("the memory transport is closed")

    def _check_type(self, topic: Topic) -> None:
        known = self._types.setdefault(topic.name, topic.type_name)
        if known != topic.type_name:
            raise WiringError(f"topic {topic.name!r} already carries {known}; cannot also use it for {topic.type_name}")

    def create_publisher(self, topic: Topic, *, owner: str | None = None) -> _MemoryPublisher:
        with self._lock:
            self._check_open()
            self._check_type(topic)
            self._stats.setdefault(topic.name, TopicStatistics())
        return _MemoryPublisher(self, topic)

    def create_subscription(
        self, topic: Topic, callback: SubscriptionCallback, *, owner: str | None = None
    ) -> _MemorySubscription:
        with self._lock:
            self._check_open()
            self._check_type(topic)
            self._stats.setdefault(topic.name, TopicStatistics())
            sub = _MemorySubscription(self, topic, callback)
            self._subscriptions.setdefault(topic.name, []).append(sub)
            if topic.qos_profile.durability == "transient_local":
                for value in self._latched.get(topic.name, ()):
                    sub._offer(value)
        return sub

    def _deliver(self, topic: Topic, value: Any) -> None:
        with self._lock:
            self._check_open()
            subs = list(self._subscriptions.get(topic.name, ()))
            self._stats[topic.name].published += 1
            if topic.qos_profile.durability == "transient_local":
                latched = self._latched.setdefault(topic.name, collections.deque(maxlen=topic.qos_profile.depth))
                latched.append(value)
        for sub in subs:
            sub._offer(value)

    def _count(self, topic_name: str, *, delivered: int = 0, dropped: int = 0, callback_errors: int = 0,
               discarded: int = 0) -> None:
        with self._lock:
            stats = self._stats.setdefault(topic_name, TopicStatistics())
            stats.delivered += delivered
            stats.dropped += dropped
            stats.callback_errors += callback_errors
            stats.discarded += discarded

    def _remove_subscription(self, sub: _MemorySubscription) -> None:
        with self._lock:
            subs = self._subscriptions.get(sub.topic.name, [])
            if sub in subs:
                subs.remove(sub)

    def statistics(self, topic_name: str | None = None) -> dict[str, TopicStatistics]:
        """Counters per topic, summed over its subscriptions, as a snapshot.

        Each value published reaches each subscription once, and there ends delivered, dropped,
        callback_errors or discarded (or is still queued).
        """
        with self._lock:
            return {
                name: TopicStatistics(s.published, s.delivered, s.dropped, s.callback_errors, s.discarded)
                for name, s in self._stats.items()
                if topic_name is None or name == topic_name
            }

    def wait_for_idle(self, timeout: float = 5.0) -> bool:
        """Block until every subscription queue is empty (for tests); True if it got there in time."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self._lock:
                subs = [s for lst in self._subscriptions.values() for s in lst]
            if all(s.statistics().queued == 0 for s in subs):
                return True
            time.sleep(0.005)
        return False

    # -- request / reply ------------------------------------------------------------------

    def create_service(self, name: str, handler: ServiceHandler, *, owner: str | None = None) -> _MemoryService:
        validate_topic_name(name, "service")
        with self._lock:
            self._check_open()
            if name in self._services:
                raise WiringError(f"service {name!r} is already served on this transport")
            self._services[name] = (handler, owner)
        return _MemoryService(self, name)

    def _remove_service(self, name: str) -> None:
        with self._lock:
            self._services.pop(name, None)

    def request(self, name: str, payload: dict[str, Any], *, timeout: float = 5.0) -> dict[str, Any]:
        timeout = check_timeout(timeout, f"request to {name!r}")
        request = with_caller_timeout(payload, timeout)
        with self._lock:
            self._check_open()
            served = self._services.get(name)
            if served is None:
                raise ServiceUnavailableError(f"no service {name!r} on this memory transport")
            handler, owner = served
            future: Future[dict[str, Any]] = self._lanes.submit(owner, serve_with_caller_deadline, handler, request,
                                                                f"request to {name!r}")
        reply: dict[str, Any] = _await_reply(name, future, timeout)
        return reply

    # -- presence -------------------------------------------------------------------------

    def declare_component(self, name: str, *, on_transition: TransitionHandler) -> _MemoryPresence:
        validate_topic_name(name, "component")
        with self._lock:
            self._check_open()
            if name in self._components:
                raise WiringError(f"a component named {name!r} is already declared on this transport")
            presence = _MemoryPresence(name=name, on_transition=on_transition, transport=self)
            self._components[name] = presence
        return presence

    def _remove_component(self, name: str) -> None:
        with self._lock:
            self._components.pop(name, None)

    def get_component_state(self, name: str, *, timeout: float = 2.0) -> ComponentStatusMsg | None:
        with self._lock:
            p = self._components.get(name)
            if p is None:
                return None
            return ComponentStatusMsg(component=name, lifecycle_state=p.state.value, health=p.health.name,
                                      message=p.message)

    def request_transition(self, name: str, transition: str, *, timeout: float = 5.0) -> bool:
        timeout = check_timeout(timeout, f"transition of {name!r}")
        with self._lock:
            self._check_open()
            p = self._components.get(name)
            if p is None:
                raise ServiceUnavailableError(f"no component {name!r} on this memory transport")
            future = self._lanes.submit(name, p.on_transition, transition)
        return bool(_await_reply(f"{name} lifecycle", future, timeout))

    # -- teardown -------------------------------------------------------------------------

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            subs = [s for lst in self._subscriptions.values() for s in lst]
            self._services.clear()
            self._components.clear()
        for sub in subs:
            sub.close()
        self._lanes.shutdown()

    def __enter__(self) -> MemoryTransport:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<MemoryTransport topics={len(self._stats)} closed={self._closed}>"


def _await_reply(name: str, future: Future[Any], timeout: float) -> Any:
    done, _ = wait([future], timeout=timeout)
    if not done:
        future.cancel()
        raise RequestTimeoutError(f"request to {name!r} got no reply within {timeout:g} s")
    # Checked apart from waiting: a handler may itself raise a TimeoutError subclass, which is
    # the service's failure, not this request's timeout.
    exc = future.exception()
    if exc is not None:
        raise RemoteError(f"{name!r} failed: {type(exc).__name__}: {exc}") from exc
    return future.result()


if TYPE_CHECKING:
    # mypy checks here that MemoryTransport satisfies the Transport protocol.
    _conforms: Transport = MemoryTransport()
