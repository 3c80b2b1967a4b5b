"""``DriverTransport``: the one transport (the public surface on top of any driver), with the bookkeeping once.

Every transport (memory, Zenoh, ROS 2, a third party's) is a :class:`DriverTransport` around a driver, whose
primitives :class:`~agents_core.transport.driver.TransportDriver` alone specifies. What lives here and nowhere else:

- the closed state (every call after :meth:`~DriverTransport.close` raises
  :class:`~agents_core.errors.TransportClosedError`), names checked, duplicate services and
  components refused, and **one type per topic** within a transport instance;
- values validated against the topic's type before a driver sends them (and when it receives them,
  unless it says ``validates_incoming``); per-topic statistics
  (:class:`~agents_core.transport.delivery.TopicStatistics`): every value received ends delivered,
  dropped, a callback error or discarded, and a payload that does not decode is counted in decode_errors;
- how a received value reaches its callback: a bounded delivery thread for user callbacks, or
  ``inline=True`` for component inputs, where the value goes straight to the component's worker
  from the middleware's thread (one hand-off per hop);
- the request lanes (one per component) and the caller's deadline (:mod:`agents_core.transport.requests`),
  for services and for transitions asked from outside;
- each component's status topic ``<name>/status``, which its state reaches only by :meth:`CorePresence.update`;
- the capabilities, derived from the driver (:func:`~agents_core.transport.driver.capabilities_of`): graph discovery
  and goals (:mod:`agents_core.transport.goal_serving`) raise TransportError where the driver lacks them.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ..errors import TransportClosedError, WiringError
from ..messages import ComponentStatusMsg
from ..status import HealthStatus, LifecycleState
from ..support.concurrency import CloseOnce
from ..supported_types import ComponentStatus
from ..telemetry import switch as _telemetry
from ..topics import QoSConfig, Topic, validate_topic_name
from .delivery import BoundedDelivery, InlineDelivery, SubscriptionStatistics, TopicCounters, TopicStatistics
from .driver import (
    Closable,
    DriverGoal,
    DriverPresence,
    DriverPublisher,
    Lane,
    ServiceHandler,
    SubscriptionCallback,
    TransitionHandler,
    TransportDriver,
    capabilities_of,
    no_discovery_error,
    no_goals_error,
)
from .goal_serving import CoreActionServer, GoalAccept, GoalExecute, abort_locally
from .goal_serving import send_goal as _send_goal
from .goals import ActionType, GoalClient, action_type, refuse_in_inline_feedback
from .graph import Graph
from .requests import RequestLanes, answer_here, check_timeout, on_lane, serve_with_caller_deadline, with_caller_timeout

if TYPE_CHECKING:
    from typing import Self

__all__ = ["CorePresence", "CorePublisher", "CoreService", "CoreSubscription", "DriverTransport", "status_topic"]

logger = logging.getLogger(__name__)

#: QoS of every ``<component>/status`` topic: a late observer gets the current status at once.
STATUS_QOS = QoSConfig(depth=5, durability="transient_local")


def status_topic(component: str) -> Topic:
    """The topic on which component ``component`` publishes its lifecycle state and health."""
    return Topic(f"{component}/status", ComponentStatus, qos_profile=STATUS_QOS)


class CorePublisher:
    """Validates values against the topic's type, counts them, and has the driver send them."""

    def __init__(self, transport: DriverTransport, topic: Topic, sender: DriverPublisher) -> None:
        self.topic = topic
        self._transport = transport
        self._sender = sender
        self._close_once = CloseOnce()
        self._validate = topic.validator()  # its TypeValidationError names the topic
        self._count_lock = transport._counters.lock
        self._totals = transport._counters.live(topic.name)
        self._traced = topic.msg_type is not ComponentStatus  # statuses: no span a second outside any trace

    @property
    def sender(self) -> DriverPublisher:
        """The driver's publisher this one sends through."""
        return self._sender

    def publish(self, value: Any) -> None:
        """Validate ``value`` and send it; TypeValidationError / TransportClosedError as the contract says."""
        if self._close_once.closed or self._transport._closed:
            raise TransportClosedError(f"publisher on {self.topic.name!r} is closed")
        value = self._validate(value)
        # Counted before sending, for the same reason as InlineDelivery.offer; undone on failure. With telemetry
        # on, a publish span is current while the driver sends: its context goes with the value.
        with self._count_lock:
            self._totals.published += 1
        span = None if (tel := _telemetry.hooks if self._traced else None) is None else tel.publish(self.topic.name)
        try:
            self._sender.send(value)
        except BaseException as exc:
            if tel is not None:
                tel.end(span, exc)
            with self._count_lock:
                self._totals.published -= 1
            raise
        if tel is not None:
            tel.end(span)

    def close(self) -> None:
        """Stop publishing; idempotent."""
        if not self._close_once.claim():
            return
        self._transport._forget(self)
        _close_quietly(self._sender, f"publisher on {self.topic.name!r}")


class _DriverHandle:
    """Something the core opened through the driver: closed once, forgotten by the transport."""

    def __init__(self, transport: DriverTransport, what: str) -> None:
        self._transport = transport
        self._what = what
        self._handle: Closable | None = None
        self._close_once = CloseOnce()

    def attach(self, handle: Closable) -> None:
        """The driver's handle, closed with this one."""
        self._handle = handle

    def _close_handle(self) -> bool:
        """Close the driver's handle; False if this ran before."""
        if not self._close_once.claim():
            return False
        self._transport._forget(self)  # type: ignore[arg-type]  # only subclasses are ever forgotten
        if self._handle is not None:
            _close_quietly(self._handle, self._what)
        return True


class CoreSubscription(_DriverHandle):
    """A driver's subscriber feeding a delivery (bounded thread or inline)."""

    def __init__(self, transport: DriverTransport, topic: Topic, delivery: BoundedDelivery | InlineDelivery) -> None:
        super().__init__(transport, f"subscription on {topic.name!r}")
        self.topic = topic
        self._delivery = delivery

    def statistics(self) -> SubscriptionStatistics:
        """Delivered / dropped / callback-error / decode-error / discarded counts."""
        return self._delivery.statistics()

    def close(self) -> None:
        """Stop receiving, then stop delivering (waiting values are discarded, counted); idempotent."""
        if self._close_handle():
            self._delivery.close()


class CoreService(_DriverHandle):
    """A service name served by the driver, its requests run on the owner's lane."""

    def __init__(self, transport: DriverTransport, name: str) -> None:
        super().__init__(transport, f"service {name!r}")
        self.name = name
        self.inline_handler: ServiceHandler | None = None  # set when a request may run it on the caller's thread

    def close(self) -> None:
        """Stop serving; idempotent."""
        self._close_handle()


class CorePresence:
    """A declared component: the driver's presence plus the component's status topic."""

    def __init__(self, transport: DriverTransport, name: str, pending: Callable[[], int] | None) -> None:
        self.name = name
        self._transport = transport
        self.pending = pending
        self._driver_presence: DriverPresence | None = None
        self._status: CorePublisher | None = None
        self._lock = threading.Lock()
        self._closed = False

    @property
    def status_publisher(self) -> CorePublisher | None:
        """The publisher of ``<name>/status`` (None until attached)."""
        return self._status

    def attach(self, driver_presence: DriverPresence) -> None:
        """The driver's presence of this component."""
        self._driver_presence = driver_presence

    def attach_status(self, status: CorePublisher) -> None:
        """The publisher of the component's status topic."""
        self._status = status

    def update(self, state: LifecycleState, health: HealthStatus, message: str = "", stats: str = "") -> None:
        """Show the component's state to observers and publish it on ``<name>/status`` (with ``stats``)."""
        with self._lock:
            if self._closed:
                return
            presence, status = self._driver_presence, self._status
        if presence is not None:
            presence.update(state, health, message)
        if status is not None:
            msg = ComponentStatusMsg(component=self.name, lifecycle_state=state.value, health=health.name,
                                     message=message, stats=stats)
            try:
                status.publish(msg)
            except TransportClosedError as exc:
                logger.debug("status of %r not published: %s", self.name, exc)

    def close(self) -> None:
        """Withdraw the component (its status topic first); idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            presence, status = self._driver_presence, self._status
        self._transport._forget(self)
        if status is not None:
            status.close()
        if presence is not None:
            _close_quietly(presence, f"component {self.name!r}")


class _SharedSender:
    """Another user of a driver publisher that stays open when this user closes."""

    def __init__(self, sender: DriverPublisher) -> None:
        self._sender = sender

    def send(self, value: Any) -> None:
        self._sender.send(value)

    def close(self) -> None:
        """The owner of the shared publisher closes it."""


def _close_quietly(handle: Closable, what: str) -> None:
    try:
        handle.close()
    except Exception as exc:  # closing twice, or after the middleware went away
        logger.debug("closing %s: %s", what, exc)


class DriverTransport:
    """The transport: the surface components, recipes and tests use, on top of a driver (module docstring).

    ``MemoryTransport``, ``ZenohTransport`` and ``Ros2Transport`` only build their driver; a third
    party's transport may be just ``DriverTransport(MyDriver(...))``.

    :param driver: the middleware driver (see :class:`~agents_core.transport.driver.TransportDriver`).
    :param request_workers: threads for requests to services that belong to no component (each component's
        requests have a lane of their own).
    """

    def __init__(self, driver: TransportDriver, *, request_workers: int = 4) -> None:
        #: The name it is resolved by ("memory", "zenoh", "ros2", or a third party's): the driver's.
        self.name = driver.name
        #: What it offers beyond the required primitives, derived from the driver.
        self.capabilities = capabilities_of(driver)
        #: The middleware driver underneath.
        self.driver = driver
        self._lock = threading.RLock()
        self._closed = False
        self._types: dict[str, str] = {}
        self._counters = TopicCounters()
        self._lanes = RequestLanes(f"{driver.name}-request", shared_workers=request_workers)
        self._open: dict[int, CorePublisher | CoreSubscription | CoreService | CorePresence] = {}
        self._services: dict[str, CoreService] = {}
        self._components: dict[str, CorePresence] = {}
        self._action_servers: dict[str, CoreActionServer] = {}
        self._sent_goals: dict[str, tuple[GoalClient, DriverGoal]] = {}

    # -- bookkeeping --------------------------------------------------------------------------

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` ran."""
        return self._closed

    def _check_open(self, what: str) -> None:
        if self._closed:
            raise TransportClosedError(f"{what}: the {self.name} transport is closed")

    def _check_type(self, topic: Topic) -> None:
        known = self._types.setdefault(topic.name, topic.type_name)
        if known != topic.type_name:
            raise WiringError(f"topic {topic.name!r} already carries {known}; cannot also use it for {topic.type_name}")

    def _forget(self, entity: CorePublisher | CoreSubscription | CoreService | CorePresence) -> None:
        with self._lock:
            self._open.pop(id(entity), None)
            if isinstance(entity, CoreService) and self._services.get(entity.name) is entity:
                del self._services[entity.name]
            if isinstance(entity, CorePresence) and self._components.get(entity.name) is entity:
                del self._components[entity.name]

    def _lane(self, owner: str | None) -> Lane:
        def submit(job: Any) -> None:
            try:
                self._lanes.submit(owner, job)
            except RuntimeError:  # closing: the request is dropped and its caller times out
                logger.debug("a request for %r arrived while closing; dropped", owner)

        return submit

    # -- pub / sub ----------------------------------------------------------------------------

    def create_publisher(self, topic: Topic, *, owner: str | None = None) -> CorePublisher:
        """A publisher for ``topic`` (``owner``: a declared component it belongs to, if any).

        ``publish(value)`` raises :class:`~agents_core.errors.TypeValidationError` for a value that does
        not fit the topic's type, :class:`~agents_core.errors.TransportClosedError` after close.
        """
        with self._lock:
            self._check_open(f"create a publisher on {topic.name!r}")
            self._check_type(topic)
            presence = self._components.get(owner) if owner is not None else None
            status = presence.status_publisher if presence is not None else None
            if status is not None and topic.name == status.topic.name:
                # A component publishing its own status shares the presence's writer: observers
                # see one writer and one stream on <name>/status, on every middleware.
                sender: DriverPublisher = _SharedSender(status.sender)
            else:
                sender = self.driver.open_publisher(topic, owner)
            publisher = CorePublisher(self, topic, sender)
            self._counters.track(topic.name)
            self._open[id(publisher)] = publisher
        return publisher

    def create_subscription(self, topic: Topic, callback: SubscriptionCallback, *, owner: str | None = None,
                            inline: bool = False) -> CoreSubscription:
        """Call ``callback(value)`` for each value received on ``topic``.

        By default on a delivery thread of the subscription's own, behind a queue of ``topic.qos_profile.depth``
        values (drop oldest, counted). With ``inline=True`` the callback runs on the middleware's thread and
        must return at once (component inputs).
        """
        if not callable(callback):
            raise WiringError(f"subscription on {topic.name!r}: callback must be callable, got {callback!r}")
        with self._lock:
            self._check_open(f"subscribe to {topic.name!r}")
            self._check_type(topic)
            delivery = (InlineDelivery if inline else BoundedDelivery)(topic, callback, self._counters)
            subscription = CoreSubscription(self, topic, delivery)
            try:
                sink = delivery if self.capabilities.validates_incoming else delivery.validating()  # see Sink.offer
                subscription.attach(self.driver.open_subscriber(topic, sink, owner))
            except BaseException:
                delivery.close()
                raise
            self._open[id(subscription)] = subscription
        return subscription

    def statistics(self, topic_name: str | None = None) -> dict[str, TopicStatistics]:
        """Per-topic counters (see :class:`~agents_core.transport.delivery.TopicStatistics`), as a snapshot."""
        return self._counters.snapshot(topic_name)

    def _busy(self) -> bool:
        with self._lock:
            entities = list(self._open.values())
        for entity in entities:
            if isinstance(entity, CoreSubscription) and entity.statistics().queued:
                return True
            if isinstance(entity, CorePresence) and entity.pending is not None and entity.pending():
                return True
        return False

    def wait_for_idle(self, timeout: float = 5.0) -> bool:
        """Block until no value waits in a subscription queue and no local component has work pending.

        For tests: True once that held twice in a row (a step may publish as it ends), False if
        ``timeout`` passed first. Values still on the wire of a networked middleware are not seen.
        """
        deadline = time.monotonic() + timeout
        quiet = 0
        while time.monotonic() < deadline:
            quiet = 0 if self._busy() else quiet + 1
            if quiet >= 2:
                return True
            time.sleep(0.005)
        return False

    # -- request / reply ----------------------------------------------------------------------

    def create_service(self, name: str, handler: ServiceHandler, *, owner: str | None = None,
                       inline: bool = False) -> CoreService:
        """Serve requests on ``name`` with ``handler``, on ``owner``'s request lane; ``inline=True``: ``handler``
        returns by the caller's deadline, and a local request may run it on its own thread (:mod:`.requests`)."""
        validate_topic_name(name, "service")
        what = f"request to {name!r}"

        def serve(request: dict[str, Any]) -> dict[str, Any]:
            return serve_with_caller_deadline(handler, request, what)

        with self._lock:
            self._check_open(f"serve {name!r}")
            if name in self._services:
                raise WiringError(f"service {name!r} is already served on this transport")
            service = CoreService(self, name)
            service.attach(self.driver.serve(name, serve, owner, self._lane(owner)))
            service.inline_handler = serve if inline and self.capabilities.local_requests else None
            self._services[name] = service
            self._open[id(service)] = service
        return service

    def request(self, name: str, payload: dict[str, Any], *, timeout: float = 5.0) -> dict[str, Any]:
        """Send ``payload`` (JSON-like) to the service ``name`` and wait for its reply.

        ``timeout`` must be a finite number of seconds > 0 (else ConfigError); a request still
        queued when it expires is never run. Errors: :meth:`TransportDriver.call
        <agents_core.transport.driver.TransportDriver.call>`; ComponentError from an inline feedback callback.
        """
        refuse_in_inline_feedback("transport.request()")
        timeout = check_timeout(timeout, f"request to {name!r}")
        self._check_open(f"request {name!r}")
        service = self._services.get(name)
        if service is not None and service.inline_handler is not None and not on_lane():
            reply = answer_here(name, service.inline_handler, payload, timeout)
        else:
            reply = self.driver.call(name, with_caller_timeout(payload, timeout), timeout)
        self._check_open(f"request {name!r}")
        return reply

    # -- presence -----------------------------------------------------------------------------

    def declare_component(self, name: str, *, on_transition: TransitionHandler,
                          pending: Callable[[], int] | None = None) -> CorePresence:
        """Make the component ``name`` visible, with its status topic; outside transitions run on its lane.

        ``pending`` tells how much work the component has queued or running (for ``wait_for_idle``).
        """
        validate_topic_name(name, "component")
        with self._lock:
            self._check_open(f"declare component {name!r}")
            if name in self._components:
                raise WiringError(f"a component named {name!r} is already declared on this transport")
            presence = CorePresence(self, name, pending)
            presence.attach(self.driver.declare_presence(name, on_transition, self._lane(name)))
            self._components[name] = presence
            self._open[id(presence)] = presence
        try:
            # The status topic is opened once the driver knows the component (owner=name puts it
            # on the component's node where the middleware has one).
            presence.attach_status(self.create_publisher(status_topic(name), owner=name))
        except BaseException:
            presence.close()
            raise
        return presence

    def get_component_state(self, name: str, *, timeout: float = 2.0) -> ComponentStatusMsg | None:
        """Read a component's lifecycle state and health as an observer would; None if not present.

        See :meth:`TransportDriver.read_state <agents_core.transport.driver.TransportDriver.read_state>`.
        """
        timeout = check_timeout(timeout, f"state of {name!r}")
        self._check_open(f"read the state of {name!r}")
        return self.driver.read_state(name, timeout)

    def request_transition(self, name: str, transition: str, *, timeout: float = 5.0) -> bool:
        """Ask the component ``name`` to run a lifecycle transition, as an outside tool would.

        See :meth:`TransportDriver.request_transition
        <agents_core.transport.driver.TransportDriver.request_transition>`.
        """
        timeout = check_timeout(timeout, f"transition of {name!r}")
        self._check_open(f"request a transition of {name!r}")
        return self.driver.request_transition(name, transition, timeout)

    def peer_process_options(self) -> dict[str, Any]:
        """The options that open, in another process, a transport reaching this one; ``{}``: this one's options.

        See :meth:`TransportDriver.peer_process_options
        <agents_core.transport.driver.TransportDriver.peer_process_options>`.
        """
        return self.driver.peer_process_options()

    # -- graph --------------------------------------------------------------------------------

    def discover(self, timeout: float = 1.0) -> Graph:
        """The topics (type, publisher and subscriber counts) and live components this transport sees.

        See :meth:`TransportDriver.discover <agents_core.transport.driver.TransportDriver.discover>`;
        raises :class:`~agents_core.errors.TransportError` where ``capabilities.discovery`` is False.
        """
        timeout = check_timeout(timeout, "discover")
        self._check_open("discover the graph")
        if not self.capabilities.discovery:
            raise no_discovery_error(self.name, self.driver)
        graph = self.driver.discover(timeout)
        self._check_open("discover the graph")
        return graph

    # -- long-running goals ---------------------------------------------------------------------

    def _action_driver(self, what: str) -> TransportDriver:
        if not self.capabilities.actions:
            raise no_goals_error(self.name, what)
        return self.driver

    def create_action_server(self, name: str, action_type_name: str | ActionType, execute: GoalExecute, *,
                             owner: str | None = None, accept: GoalAccept | None = None) -> CoreActionServer:
        """Serve goals of ``action_type_name`` on ``name``: each accepted goal runs ``execute`` on a thread of its own.

        ``accept(goal)`` decides whether a validated goal is accepted (default: every goal, up to
        :data:`~agents_core.transport.goal_serving.MAX_RUNNING_GOALS` at once). Raises
        :class:`~agents_core.errors.UnknownTypeError` for an unknown action type and
        :class:`~agents_core.errors.TransportError` on a transport without goals.
        """
        validate_topic_name(name, "action")
        definition = action_type(action_type_name)
        with self._lock:
            self._check_open(f"serve the action {name!r}")
            driver = self._action_driver(f"serve the action {name!r}")
            if name in self._action_servers:
                raise WiringError(f"action {name!r} is already served on this transport")
            server = CoreActionServer(name, definition, execute, accept, owner, self._forget_action_server)
            server.attach(driver.serve_goals(name, definition, server, owner, server.lane(self._lane(owner))))
            self._action_servers[name] = server
        return server

    def _forget_action_server(self, server: CoreActionServer) -> None:
        with self._lock:
            if self._action_servers.get(server.name) is server:
                del self._action_servers[server.name]

    def send_goal(self, name: str, action_type_name: str | ActionType, goal: dict[str, Any], *,
                  feedback: Callable[[dict[str, Any]], None] | None = None, timeout: float = 5.0,
                  feedback_inline: bool = False) -> GoalClient:
        """Send ``goal`` to the action ``name`` and wait up to ``timeout`` for it to be accepted or rejected.

        Returns a :class:`~agents_core.transport.goals.GoalClient` (a rejected goal comes back with status
        REJECTED and the reason in its result). ``feedback`` is called with each feedback dict on a thread of
        the goal's own; ``feedback_inline=True``: on the driver's, no hand-off, for a callback that returns at
        once and never waits (``goal.cancel()``, ``goal.result()``, ``send_goal`` and ``request`` raise
        ComponentError there, ``goal.cancel_async()`` does not wait; see :func:`.goal_serving.send_goal`).
        Raises TypeValidationError (a goal that does not fit the type), ServiceUnavailableError (nobody serves
        ``name``), RequestTimeoutError (no answer in time), from :mod:`agents_core.errors`."""
        validate_topic_name(name, "action")
        timeout = check_timeout(timeout, f"goal to {name!r}")
        definition = action_type(action_type_name)
        self._check_open(f"send a goal to {name!r}")
        client, handle = _send_goal(self._action_driver(f"send a goal to {name!r}"), name, definition, goal,
                                    feedback, timeout, self._forget_goal, feedback_inline)
        with self._lock:
            closed = self._closed
            if not closed and not client.done:
                self._sent_goals[client.goal_id] = (client, handle)
        if closed:
            abort_locally(client, f"the {self.name} transport closed")
        return client

    def _forget_goal(self, client: GoalClient) -> None:
        with self._lock:
            self._sent_goals.pop(client.goal_id, None)

    # -- teardown -----------------------------------------------------------------------------

    def close(self) -> None:
        """Withdraw every component, then subscriptions, services, publishers; then the driver. Idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            # Components first, so observers see them go before their topics fall silent.
            entities = sorted(self._open.values(), key=lambda e: not isinstance(e, CorePresence))
            servers = list(self._action_servers.values())
            sent = list(self._sent_goals.values())
        # Action servers before anything else: their clients get ABORTED with the reason.
        for server in servers:
            try:
                server.close()
            except Exception as exc:
                logger.debug("closing action server %r failed: %s", server.name, exc)
        for client, handle in sent:
            abort_locally(client, f"the {self.name} transport closed before the goal ended")
            _close_quietly(handle, f"goal {client.goal_id}")
        for entity in entities:
            try:
                entity.close()
            except Exception as exc:
                logger.debug("closing %r failed: %s", entity, exc)
        self._lanes.shutdown()
        self.driver.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} driver={self.driver!r} closed={self._closed}>"
