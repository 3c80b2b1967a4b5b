"""The in-memory transport: one process, no encoding, bounded queues, statistics.

This is what unit tests (the framework's and users') run on. Each :class:`MemoryTransport` is
independent (no global state), thread-safe, and delivers the publisher's value object itself
to every subscriber (zero-copy: treat received values as read-only).

Queue policy: each subscription has its own queue of ``topic.qos_profile.depth`` values and its
own delivery thread, so a slow subscriber never blocks a publisher or another subscriber. When
its queue is full the **oldest** queued value is dropped and counted
(:attr:`SubscriptionStatistics.dropped`, and per topic in :meth:`MemoryTransport.statistics`).
Component inputs (``inline=True``) skip that queue: the publisher's thread hands the value to
the component's worker. With ``durability="transient_local"`` the last ``depth`` values of a
topic are replayed to a subscriber that joins late. Its services all live in this process
(``local_requests``), so a request to an ``inline`` one (a component's own services) may run its
handler on the caller's thread (:mod:`agents_core.transport.requests`).
"""

from __future__ import annotations

import collections
import threading
from concurrent.futures import Future, wait
from typing import Any

from attrs import define

from ..errors import RemoteError, RequestTimeoutError, ServiceUnavailableError
from ..messages import ComponentStatusMsg
from ..status import HealthStatus, LifecycleState
from ..topics import Topic
from .core import DriverTransport
from .delivery import SubscriptionStatistics, TopicStatistics
from .driver import DriverBase, GoalEvents, GoalServerHooks, Lane, ServiceHandler, Sink, TransitionHandler
from .goals import ActionType, GoalStatus
from .graph import Graph, TopicInfo

__all__ = ["MemoryDriver", "MemoryTransport", "SubscriptionStatistics", "TopicStatistics"]


class _Sender:
    def __init__(self, driver: MemoryDriver, topic: Topic) -> None:
        self._driver = driver
        self._topic = topic

    def send(self, value: Any) -> None:
        self._driver._deliver(self._topic, value)

    def close(self) -> None:
        """Withdraw from the graph (nothing else to release in memory)."""
        self._driver._remove_sender(self)


class _Receiver:
    def __init__(self, driver: MemoryDriver, topic: Topic, sink: Sink) -> None:
        self.topic = topic
        self.sink = sink
        self._driver = driver

    def close(self) -> None:
        self._driver._remove(self)


class _Served:
    def __init__(self, driver: MemoryDriver, name: str, handler: ServiceHandler, lane: Lane) -> None:
        self.name = name
        self.handler = handler
        self.lane = lane
        self._driver = driver

    def close(self) -> None:
        with self._driver._lock:
            if self._driver._services.get(self.name) is self:
                del self._driver._services[self.name]


@define
class _MemoryPresence:
    name: str
    on_transition: TransitionHandler
    lane: Lane
    driver: MemoryDriver
    state: LifecycleState = LifecycleState.UNCONFIGURED
    health: HealthStatus = HealthStatus.HEALTHY
    message: str = ""

    def update(self, state: LifecycleState, health: HealthStatus, message: str) -> None:
        self.state, self.health, self.message = state, health, message

    def close(self) -> None:
        with self.driver._lock:
            if self.driver._components.get(self.name) is self:
                del self.driver._components[self.name]


def _run_on_lane(lane: Lane, func: Any, *args: Any) -> Future[Any]:
    future: Future[Any] = Future()

    def job() -> None:
        if not future.set_running_or_notify_cancel():
            return
        try:
            future.set_result(func(*args))
        except BaseException as exc:
            future.set_exception(exc)

    lane(job)
    return future


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


class _MemoryActionServer:
    """An action server in memory: goals are handed to the core's hooks, events straight to the clients."""

    def __init__(self, driver: MemoryDriver, name: str, hooks: GoalServerHooks, lane: Lane) -> None:
        self.name = name
        self.hooks = hooks
        self.lane = lane
        self._driver = driver
        self._clients: dict[str, GoalEvents] = {}
        self._lock = threading.Lock()

    def _events(self, goal_id: str) -> GoalEvents | None:
        with self._lock:
            return self._clients.get(goal_id)

    def feedback(self, goal_id: str, feedback: dict[str, Any]) -> None:
        events = self._events(goal_id)
        if events is not None:
            events.feedback(feedback)

    def status(self, goal_id: str, status: GoalStatus) -> None:
        events = self._events(goal_id)
        if events is not None:
            events.status(status)

    def finish(self, goal_id: str, status: GoalStatus, result: dict[str, Any]) -> None:
        with self._lock:
            events = self._clients.pop(goal_id, None)
        if events is not None:
            events.finished(status, result)

    def close(self) -> None:
        with self._driver._lock:
            if self._driver._actions.get(self.name) is self:
                del self._driver._actions[self.name]
        with self._lock:
            orphans, self._clients = list(self._clients.values()), {}
        for events in orphans:
            events.finished(GoalStatus.ABORTED, {"message": f"action server {self.name!r} closed"})


class _MemoryGoal:
    """A sent goal in memory."""

    def __init__(self, server: _MemoryActionServer, goal_id: str, accepted: bool, reason: str) -> None:
        self.accepted = accepted
        self.reason = reason
        self._server = server
        self._goal_id = goal_id

    def cancel(self, timeout: float) -> bool:
        return self._server.hooks.on_cancel(self._goal_id)

    def close(self) -> None:
        with self._server._lock:
            self._server._clients.pop(self._goal_id, None)


class MemoryDriver(DriverBase):
    """The memory transport's driver: subscribers, services and components in dictionaries."""

    name = "memory"
    #: Its services are this object's: an ``inline`` one may answer on the caller's thread.
    local_requests = True
    #: What it hands a subscriber was validated by the core's publisher in this very process.
    validates_incoming = True

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._receivers: dict[str, list[_Receiver]] = {}
        self._latched: dict[str, collections.deque[Any]] = {}
        self._services: dict[str, _Served] = {}
        self._components: dict[str, _MemoryPresence] = {}
        self._senders: dict[str, list[_Sender]] = {}
        self._actions: dict[str, _MemoryActionServer] = {}

    def open_publisher(self, topic: Topic, owner: str | None) -> _Sender:
        sender = _Sender(self, topic)
        with self._lock:
            self._senders.setdefault(topic.name, []).append(sender)
        return sender

    def _remove_sender(self, sender: _Sender) -> None:
        with self._lock:
            current = self._senders.get(sender._topic.name, [])
            if sender in current:
                current.remove(sender)

    def discover(self, timeout: float) -> Graph:
        """The topics with open publishers or subscribers, and the declared components (no waiting)."""
        with self._lock:
            names = {n for n, s in self._senders.items() if s} | {n for n, r in self._receivers.items() if r}
            topics = []
            for name in names:
                senders, receivers = self._senders.get(name, []), self._receivers.get(name, [])
                topic = senders[0]._topic if senders else receivers[0].topic
                topics.append(TopicInfo(name=name.lstrip("/"), msg_type=topic.type_name, publishers=len(senders),
                                        subscribers=len(receivers)))
            return Graph(topics=topics, components=list(self._components))

    def open_subscriber(self, topic: Topic, sink: Sink, owner: str | None) -> _Receiver:
        receiver = _Receiver(self, topic, sink)
        with self._lock:
            # A copy per change, so _deliver can read the list without the lock.
            self._receivers[topic.name] = [*self._receivers.get(topic.name, ()), receiver]
            replay = list(self._latched.get(topic.name, ())) if topic.qos_profile.durability == "transient_local" \
                else []
        for value in replay:
            sink.offer(value)
        return receiver

    def _deliver(self, topic: Topic, value: Any) -> None:
        if topic.qos_profile.durability == "transient_local":
            with self._lock:
                latched = self._latched.setdefault(topic.name, collections.deque(maxlen=topic.qos_profile.depth))
                latched.append(value)
        for receiver in self._receivers.get(topic.name, ()):
            receiver.sink.offer(value)

    def _remove(self, receiver: _Receiver) -> None:
        with self._lock:
            current = self._receivers.get(receiver.topic.name, [])
            self._receivers[receiver.topic.name] = [r for r in current if r is not receiver]

    def serve(self, name: str, handler: ServiceHandler, owner: str | None, lane: Lane) -> _Served:
        served = _Served(self, name, handler, lane)
        with self._lock:
            self._services[name] = served
        return served

    def call(self, name: str, payload: dict[str, Any], timeout: float) -> dict[str, Any]:
        with self._lock:
            served = self._services.get(name)
        if served is None:
            raise ServiceUnavailableError(f"no service {name!r} on this memory transport")
        reply: dict[str, Any] = _await_reply(name, _run_on_lane(served.lane, served.handler, payload), timeout)
        return reply

    def declare_presence(self, name: str, on_transition: TransitionHandler, lane: Lane) -> _MemoryPresence:
        presence = _MemoryPresence(name=name, on_transition=on_transition, lane=lane, driver=self)
        with self._lock:
            self._components[name] = presence
        return presence

    def read_state(self, name: str, timeout: float) -> ComponentStatusMsg | None:
        with self._lock:
            p = self._components.get(name)
        if p is None:
            return None
        return ComponentStatusMsg(component=name, lifecycle_state=p.state.value, health=p.health.name,
                                  message=p.message)

    def request_transition(self, name: str, transition: str, timeout: float) -> bool:
        with self._lock:
            p = self._components.get(name)
        if p is None:
            raise ServiceUnavailableError(f"no component {name!r} on this memory transport")
        return bool(_await_reply(f"{name} lifecycle", _run_on_lane(p.lane, p.on_transition, transition), timeout))

    def serve_goals(self, name: str, definition: ActionType, hooks: GoalServerHooks, owner: str | None,
                    lane: Lane) -> _MemoryActionServer:
        server = _MemoryActionServer(self, name, hooks, lane)
        with self._lock:
            self._actions[name] = server
        return server

    def send_goal(self, name: str, definition: ActionType, goal_id: str, goal: dict[str, Any], events: GoalEvents,
                  timeout: float) -> _MemoryGoal:
        with self._lock:
            server = self._actions.get(name)
        if server is None:
            raise ServiceUnavailableError(f"no action server {name!r} on this memory transport")
        with server._lock:
            server._clients[goal_id] = events
        hooks = server.hooks

        def decide() -> str | None:
            reason = hooks.on_goal(goal_id, goal)
            if reason is None:
                hooks.on_accepted(goal_id)
            return reason

        # The accept decision may run user code: on the lane the core gives (a goal thread of the server's).
        try:
            reason = _await_reply(f"goal to {name!r}", _run_on_lane(server.lane, decide), timeout)
        except RequestTimeoutError:
            # Accepted after its sender gave up, the goal would run for nobody: cancel it (best effort).
            with server._lock:
                server._clients.pop(goal_id, None)
            hooks.on_cancel(goal_id)
            raise
        if reason is not None:
            with server._lock:
                server._clients.pop(goal_id, None)
            return _MemoryGoal(server, goal_id, False, reason)
        return _MemoryGoal(server, goal_id, True, "")

    def close(self) -> None:
        with self._lock:
            self._actions.clear()
            self._receivers.clear()
            self._senders.clear()
            self._services.clear()
            self._components.clear()

    def __repr__(self) -> str:
        return f"<MemoryDriver topics={len(self._receivers)}>"


class MemoryTransport(DriverTransport):
    """In-process transport for tests and single-process robots: a DriverTransport around a :class:`MemoryDriver`.

    ``request_workers`` bounds how many requests for services without an owner run at once;
    each component's requests run on a lane of their own (see
    :mod:`agents_core.transport.requests`).
    """

    driver: MemoryDriver

    def __init__(self, *, request_workers: int = 4) -> None:
        super().__init__(MemoryDriver(), request_workers=request_workers)
