"""The transport contract: what every transport offers its users (components, recipes, tests).

Triggers, scheduling, events, fallbacks, validation and retries live once in the core. A
middleware adapter implements only the small driver contract in
:mod:`agents_core.transport.driver`; :class:`~agents_core.transport.core.DriverTransport` turns
any driver into a :class:`Transport`, which promises:

1. publishers for a :class:`~agents_core.topics.Topic` (values validated with the topic's type,
   then encoded with the adapter's conversion for that type);
2. subscriptions that decode into the core value and hand it to a
   :class:`~agents_core.transport.delivery.BoundedDelivery`, which applies the shared queue
   policy (depth from the topic's QoS, drop oldest, counted) and calls back on its own thread,
   so a slow or raising callback never stalls the middleware;
3. request/reply by service name, with JSON-like payloads (dicts of str, int, float, bool,
   None, lists and dicts) and a timeout that always fires;
4. component presence: a component declared here is visible to the middleware's users with its
   lifecycle state and health, and may be driven through ``on_transition``;
5. ``close()``, after which every call raises :class:`~agents_core.errors.TransportClosedError`;
6. per-topic ``statistics()`` (published, delivered, dropped, callback errors, discarded,
   decode errors), so that no value is ever lost uncounted;
7. where ``capabilities.actions`` is True, long-running goals: ``create_action_server`` and
   ``send_goal`` (:mod:`agents_core.transport.goals`); elsewhere both raise
   :class:`~agents_core.errors.TransportError`.

What a transport can do beyond that is data (:class:`TransportCapabilities`), not subclassing.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

from attrs import define

from ..messages import ComponentStatusMsg
from ..status import HealthStatus, LifecycleState
from ..topics import Topic
from .delivery import SubscriptionStatistics, TopicStatistics
from .goals import ActionType, GoalClient, GoalHandle

__all__ = [
    "ActionServer",
    "ComponentPresence",
    "Publisher",
    "ServiceHandler",
    "ServiceServer",
    "Subscription",
    "SubscriptionCallback",
    "TransitionHandler",
    "Transport",
    "TransportCapabilities",
]

#: Called with each received value (already decoded and validated).
SubscriptionCallback = Callable[[Any], None]
#: Serves one request: JSON-like dict in, JSON-like dict out. Raising sends the error back.
ServiceHandler = Callable[[dict[str, Any]], dict[str, Any]]
#: Asked to run a lifecycle transition ("configure", "activate", ...); returns success.
TransitionHandler = Callable[[str], bool]


@define(frozen=True, kw_only=True)
class TransportCapabilities:
    """What a transport offers beyond the contract, as data the core decides on (never its name)."""

    #: Components may live in different processes (read by the Launcher for ``multiprocessing``).
    cross_process: bool
    #: Long-running goals with feedback (read by components that run as action servers).
    actions: bool = False


@runtime_checkable
class Publisher(Protocol):
    """Sends values on one topic."""

    topic: Topic

    def publish(self, value: Any) -> None:
        """Validate ``value`` against the topic's type and send it.

        Raises :class:`~agents_core.errors.TypeValidationError` for a value that does not fit,
        :class:`~agents_core.errors.TransportClosedError` after close.
        """
        ...

    def close(self) -> None:
        """Stop publishing; idempotent."""
        ...


@runtime_checkable
class Subscription(Protocol):
    """Receives values of one topic and hands them to a callback."""

    topic: Topic

    def statistics(self) -> SubscriptionStatistics:
        """Delivered / dropped / callback-error counts (adapters get them from BoundedDelivery)."""
        ...

    def close(self) -> None:
        """Stop receiving; no callback starts after this returns. Idempotent."""
        ...


@runtime_checkable
class ServiceServer(Protocol):
    """Serves requests on one service name."""

    name: str

    def close(self) -> None:
        """Stop serving; idempotent."""
        ...


@runtime_checkable
class ActionServer(Protocol):
    """Serves long-running goals on one action name."""

    name: str

    def close(self) -> None:
        """Abort the goals still running (their clients get ABORTED with the reason), stop serving; idempotent."""
        ...


@runtime_checkable
class ComponentPresence(Protocol):
    """A component as the middleware's users see it (lifecycle node, liveliness token, ...)."""

    name: str

    def update(self, state: LifecycleState, health: HealthStatus, message: str = "") -> None:
        """Show the component's current lifecycle state and health, and publish it on ``<name>/status``."""
        ...

    def close(self) -> None:
        """Withdraw the component (it disappears for observers); idempotent."""
        ...


@runtime_checkable
class Transport(Protocol):
    """A middleware adapter. See the module docstring for the promises an implementer makes."""

    #: The name it is resolved by ("memory", "zenoh", "ros2", or a third party's).
    name: str
    capabilities: TransportCapabilities

    def create_publisher(self, topic: Topic, *, owner: str | None = None) -> Publisher:
        """A publisher for ``topic``. ``owner`` names a declared component it belongs to, if any."""
        ...

    def create_subscription(
        self, topic: Topic, callback: SubscriptionCallback, *, owner: str | None = None, inline: bool = False
    ) -> Subscription:
        """Call ``callback(value)`` for each value received on ``topic``.

        By default off the publisher's and the middleware's threads, on a bounded delivery
        thread; ``inline=True`` calls it on the middleware's thread, for callbacks that return
        at once (the core's component inputs, which only enqueue a step).
        """
        ...

    def create_service(self, name: str, handler: ServiceHandler, *, owner: str | None = None) -> ServiceServer:
        """Serve requests on ``name`` (a topic-like name) with ``handler``."""
        ...

    def statistics(self, topic_name: str | None = None) -> dict[str, TopicStatistics]:
        """Per-topic counters of this transport instance (every topic, or ``topic_name`` only).

        ``published`` counts values sent from here; the other counters sum over the local
        subscriptions of the topic, so that each value received ends in exactly one of
        delivered, dropped, callback_errors or discarded, and a payload that does not decode is
        counted in decode_errors.
        """
        ...

    def request(self, name: str, payload: dict[str, Any], *, timeout: float = 5.0) -> dict[str, Any]:
        """Send ``payload`` to the service ``name`` and wait for its reply.

        ``timeout`` must be a finite number of seconds > 0 (else ConfigError); the handler of a
        request still queued when the caller's timeout expires is never run (see
        :mod:`agents_core.transport.requests`). Raises
        :class:`~agents_core.errors.RequestTimeoutError` after ``timeout`` seconds,
        :class:`~agents_core.errors.ServiceUnavailableError` when nobody serves ``name``, and
        :class:`~agents_core.errors.RemoteError` with the handler's message when it raised.
        """
        ...

    def declare_component(self, name: str, *, on_transition: TransitionHandler,
                          pending: Callable[[], int] | None = None) -> ComponentPresence:
        """Make the component ``name`` visible; ``on_transition`` runs transitions asked from outside.

        Its status topic ``<name>/status`` is the transport's: :meth:`ComponentPresence.update`
        publishes there. ``pending`` reports the component's queued and running work.
        """
        ...

    def get_component_state(self, name: str, *, timeout: float = 2.0) -> ComponentStatusMsg | None:
        """Read a component's lifecycle state and health as an observer would; None if not present."""
        ...

    def create_action_server(self, name: str, action_type_name: str | ActionType,
                             execute: Callable[[GoalHandle], dict[str, Any]], *, owner: str | None = None,
                             accept: Callable[[dict[str, Any]], bool] | None = None) -> ActionServer:
        """Serve goals on ``name``; each accepted goal runs ``execute(handle)`` on a thread of its own."""
        ...

    def send_goal(self, name: str, action_type_name: str | ActionType, goal: dict[str, Any], *,
                  feedback: Callable[[dict[str, Any]], None] | None = None, timeout: float = 5.0) -> GoalClient:
        """Send a goal to the action ``name``; returns once it is accepted or rejected."""
        ...

    def request_transition(self, name: str, transition: str, *, timeout: float = 5.0) -> bool:
        """Ask the component ``name`` to run a lifecycle transition, as an outside tool would."""
        ...

    def close(self) -> None:
        """Release every publisher, subscription, service and presence; idempotent."""
        ...
