"""The driver contract: the primitives a middleware adapter implements, each specified here and only here.

A middleware adapter is a *driver*: a subclass of :class:`DriverBase` that implements the
required primitives of :class:`TransportDriver` and, where its middleware can, the optional ones.
:class:`~agents_core.transport.core.DriverTransport` puts the public transport surface on top of any
driver and keeps the rest once, for every driver: validation against the topic's type (of each value
before the driver sends it; of each value it receives too, unless the driver declares
``validates_incoming``, see :meth:`Sink.offer`), the closed state, duplicate names, one type per
topic, statistics, the request lanes (one per component), the caller's deadline, the status topic of
each component, the delivery of received values (a thread for user callbacks, straight to the
component's worker for component inputs), and the goal bookkeeping
(:mod:`agents_core.transport.goal_serving`).

What a driver offers is data, derived from the class (:func:`capabilities_of`): ``actions`` when
it overrides both goal primitives, ``discovery`` when it overrides :meth:`~TransportDriver.discover`;
``cross_process``, ``discovery_settle_s``, ``local_requests`` and ``validates_incoming`` are declared
as class attributes.

Errors: a driver raises the core's errors (:class:`~agents_core.errors.RequestTimeoutError`,
:class:`~agents_core.errors.ServiceUnavailableError`, :class:`~agents_core.errors.RemoteError`,
:class:`~agents_core.errors.TransportError`), mapping its middleware's own.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, ClassVar, Protocol, runtime_checkable

from attrs import define

from ..errors import TransportError
from ..messages import ComponentStatusMsg
from ..status import HealthStatus, LifecycleState
from ..topics import Topic
from .goals import ActionType, GoalStatus
from .graph import Graph

__all__ = [
    "Closable",
    "DriverActionServer",
    "DriverBase",
    "DriverGoal",
    "DriverPresence",
    "DriverPublisher",
    "GoalEvents",
    "GoalServerHooks",
    "Lane",
    "ServiceHandler",
    "Sink",
    "SubscriptionCallback",
    "TransitionHandler",
    "TransportCapabilities",
    "TransportDriver",
    "capabilities_of",
    "no_discovery_error",
    "no_goals_error",
]

#: Called with each received value (already decoded and validated).
SubscriptionCallback = Callable[[Any], None]
#: Serves one request: JSON-like dict in, JSON-like dict out. Raising sends the error back.
ServiceHandler = Callable[[dict[str, Any]], dict[str, Any]]
#: Asked to run a lifecycle transition ("configure", "activate", ...); returns success.
TransitionHandler = Callable[[str], bool]
#: Runs a job on the request lane of the owner of a service or component (never blocks).
Lane = Callable[[Callable[[], None]], None]


@define(frozen=True, kw_only=True)
class TransportCapabilities:
    """What a transport offers beyond the required primitives, as data the core decides on (never its name).

    Derived from the driver by :func:`capabilities_of`.
    """

    #: Components may live in different processes (read by the Launcher for ``multiprocessing``).
    cross_process: bool
    #: Long-running goals with feedback (read by components that run as action servers).
    actions: bool = False
    #: ``discover()`` sees the graph (read by the CLI and the web UI).
    discovery: bool = False
    #: Seconds a fresh observer waits by default for the middleware's discovery to settle.
    discovery_settle_s: float = 1.0
    #: Every service it serves lives in this process, on this transport: a request to an ``inline``
    #: service may be answered on the caller's thread (read by ``DriverTransport.request``).
    local_requests: bool = False
    #: The driver validates each received value against the topic's type before offering it (it
    #: checks as it decodes, and hands what does not validate to ``Sink.reject``, never to
    #: ``Sink.offer``); when False the core does (read by ``DriverTransport.create_subscription``).
    validates_incoming: bool = False


@runtime_checkable
class Sink(Protocol):
    """Where a driver hands what it receives on one topic (given by the core)."""

    def offer(self, value: Any) -> None:
        """A decoded value. Never blocks, never raises.

        Each value is validated against the topic's type exactly once before anyone sees it: by
        the driver, as it decodes, when the driver declares ``validates_incoming = True`` (Zenoh's
        codecs, the ROS 2 conversions, the memory transport's already validated values); else by
        the core, which wraps this sink so that a value that does not validate is rejected
        (counted as a decode error) instead of reaching a component.
        """
        ...

    def reject(self, reason: object) -> None:
        """A payload that did not decode, with why. Never blocks, never raises."""
        ...


@runtime_checkable
class Closable(Protocol):
    """A handle the core closes exactly once."""

    def close(self) -> None:
        """Release the middleware entity."""
        ...


@runtime_checkable
class DriverPublisher(Protocol):
    """Sends one topic's values."""

    def send(self, value: Any) -> None:
        """Encode and send ``value``, already validated against the topic's type."""
        ...

    def close(self) -> None:
        """Release the middleware publisher."""
        ...


@runtime_checkable
class DriverPresence(Protocol):
    """A component as the middleware's users see it."""

    def update(self, state: LifecycleState, health: HealthStatus, message: str) -> None:
        """Show the component's current state (the status topic is the core's, not the driver's)."""
        ...

    def close(self) -> None:
        """Withdraw the component."""
        ...


@runtime_checkable
class TransportDriver(Protocol):
    """A middleware adapter's primitives: the one specification of each (implement by subclassing :class:`DriverBase`).

    Required: :meth:`open_publisher`, :meth:`open_subscriber`, :meth:`serve`, :meth:`call`,
    :meth:`declare_presence`, :meth:`read_state`, :meth:`request_transition`, :meth:`close`.
    Optional, with defaults on :class:`DriverBase`: :meth:`discover`, :meth:`serve_goals` with
    :meth:`send_goal`, and :meth:`peer_process_options`.
    """

    #: The name the transport is resolved by ("memory", "zenoh", "ros2", or a third party's).
    name: str
    #: Whether components may live in different processes (``Launcher(multiprocessing=True)``).
    cross_process: bool
    #: Seconds a fresh observer waits by default for :meth:`discover` to see the graph.
    discovery_settle_s: float

    def open_publisher(self, topic: Topic, owner: str | None) -> DriverPublisher:
        """A publisher for ``topic`` (``owner``: the declared component it belongs to, if any).

        The core validates each value against the topic's type, refuses it after close and counts
        it before calling ``send``.
        """
        ...

    def open_subscriber(self, topic: Topic, sink: Sink, owner: str | None) -> Closable:
        """Hand what arrives on ``topic`` to ``sink`` until closed.

        Decode each payload and call ``sink.offer(value)``, or ``sink.reject(reason)`` for one that
        does not decode; both return at once and never raise, so call them from the middleware's
        own thread. The core chooses the sink (a bounded delivery thread for user callbacks, inline
        to a component's worker for component inputs) and counts what becomes of each value.
        """
        ...

    def serve(self, name: str, handler: ServiceHandler, owner: str | None, lane: Lane) -> Closable:
        """Answer requests on ``name`` until closed.

        For each request call ``lane(job)``, where ``job()`` runs ``handler(request)`` and sends back
        its reply (a dict) or its error. The lane is the owner's (a busy component never delays
        another's requests); the handler the core gives already drops a request whose caller gave up.
        """
        ...

    def call(self, name: str, payload: dict[str, Any], timeout: float) -> dict[str, Any]:
        """Send ``payload`` to the service ``name`` and return its reply.

        ``timeout`` is checked by the core (finite, > 0), and ``payload`` carries the caller's
        deadline. Raises :class:`~agents_core.errors.RequestTimeoutError` after ``timeout`` seconds,
        :class:`~agents_core.errors.ServiceUnavailableError` when nobody serves ``name``, and
        :class:`~agents_core.errors.RemoteError` with the handler's message when it raised.
        """
        ...

    def declare_presence(self, name: str, on_transition: TransitionHandler, lane: Lane) -> DriverPresence:
        """Make component ``name`` visible to the middleware's users until closed.

        Transitions asked from outside (:meth:`request_transition` of another process) run
        ``on_transition`` through ``lane``. The core refuses duplicate names and publishes the
        component's status topic ``<name>/status`` on every ``update``.
        """
        ...

    def read_state(self, name: str, timeout: float) -> ComponentStatusMsg | None:
        """Component ``name``'s lifecycle state and health as an outside observer reads them; None if absent.

        Waits at most ``timeout`` seconds (checked by the core) for the component to answer.
        """
        ...

    def request_transition(self, name: str, transition: str, timeout: float) -> bool:
        """Ask component ``name`` for ``transition`` as an outside tool would; whether it was done.

        Raises :class:`~agents_core.errors.ServiceUnavailableError` when no such component
        appears and :class:`~agents_core.errors.RequestTimeoutError` when it does not answer
        within ``timeout``.
        """
        ...

    def close(self) -> None:
        """Release the session, nodes and threads; the core has closed every handle before."""
        ...

    # -- optional (defaults on DriverBase) -----------------------------------------------------

    def discover(self, timeout: float) -> Graph:
        """Optional: every topic (name, type, publisher and subscriber counts) and live component this driver sees.

        Waits at most ``timeout`` seconds for the middleware's discovery to settle; what was not
        seen by then is not in the graph. Overriding it turns ``capabilities.discovery`` on; the
        default raises :class:`~agents_core.errors.TransportError` saying the transport does not
        support discovery.
        """
        ...

    def serve_goals(self, name: str, definition: ActionType, hooks: GoalServerHooks, owner: str | None,
                    lane: Lane) -> DriverActionServer:
        """Optional: serve goals of ``definition`` on ``name`` until the returned server is closed.

        Carry each goal to ``hooks.on_goal(goal_id, goal)`` (None means accepted, else the reason;
        run it through ``lane`` where the middleware's thread must not wait), then
        ``hooks.on_accepted(goal_id)``; cancels to ``hooks.on_cancel``, result requests to
        ``hooks.wait_result``, and what does not decode to ``hooks.reject``. The core validates
        goals, feedback and results, keeps goal ids, the ``accept`` callback, a thread per goal and
        the results for late requests.

        Overriding it together with :meth:`send_goal` turns ``capabilities.actions`` on; the
        default raises :class:`~agents_core.errors.TransportError` (no long-running goals).
        """
        ...

    def send_goal(self, name: str, definition: ActionType, goal_id: str, goal: dict[str, Any],
                  events: GoalEvents, timeout: float) -> DriverGoal:
        """Optional: send a validated goal, wait (up to ``timeout``) for its acceptance, then feed ``events``.

        Feed ``events.feedback / status / finished / reject`` until the goal ends, and call
        ``events.finished(GoalStatus.ABORTED, {"message": why})`` when the server goes away.
        Raises :class:`~agents_core.errors.ServiceUnavailableError` when nobody serves ``name``
        within ``timeout`` and :class:`~agents_core.errors.RequestTimeoutError` when the server
        does not answer in time. Default and capability: see :meth:`serve_goals`.
        """
        ...

    def peer_process_options(self) -> dict[str, Any]:
        """Optional: the options that open, in another process, a transport reaching this one.

        Read by ``Launcher(multiprocessing=True)`` for each component's process. The default,
        ``{}``, means the options this transport was opened with.
        """
        ...


# -- long-running goals: what the core and a driver hand each other ---------------------------------


@runtime_checkable
class GoalServerHooks(Protocol):
    """What the core gives a driver's action server; every method is safe on any thread."""

    def on_goal(self, goal_id: str, goal: Any) -> str | None:
        """A goal arrived (decoded, not yet validated): None if accepted, else why it was rejected.

        May run the server's ``accept`` callback (user code): call it through the lane given to
        :meth:`TransportDriver.serve_goals` where the middleware's thread must not wait. Never raises.
        """
        ...

    def on_accepted(self, goal_id: str) -> None:
        """Start the accepted goal (once the driver can carry its feedback and status)."""
        ...

    def on_cancel(self, goal_id: str) -> bool:
        """A client asked to cancel ``goal_id``: whether the goal was running (and is now canceling)."""
        ...

    def wait_result(self, goal_id: str, timeout: float) -> tuple[GoalStatus, dict[str, Any]] | None:
        """The goal's terminal status and result once it has ended; None if it still runs after ``timeout``.

        ``(GoalStatus.UNKNOWN, {})`` for a goal id this server does not know (never accepted, or
        forgotten long ago).
        """
        ...

    def reject(self, reason: object) -> None:
        """A goal, cancel or result request that did not decode, with why (counted)."""
        ...


@runtime_checkable
class DriverActionServer(Protocol):
    """Carries one action server's goal events to its clients (returned by :meth:`TransportDriver.serve_goals`)."""

    def feedback(self, goal_id: str, feedback: dict[str, Any]) -> None:
        """Send validated ``feedback`` of a running goal to its client."""
        ...

    def status(self, goal_id: str, status: GoalStatus) -> None:
        """The goal's status changed (EXECUTING, CANCELING, or a terminal one just before :meth:`finish`)."""
        ...

    def finish(self, goal_id: str, status: GoalStatus, result: dict[str, Any]) -> None:
        """The goal ended with ``status`` and the validated ``result``: make it available to the client."""
        ...

    def close(self) -> None:
        """Stop serving (the core has finished every goal before)."""
        ...


@runtime_checkable
class GoalEvents(Protocol):
    """Where a driver hands what arrives for one sent goal; return at once, never raise."""

    def feedback(self, feedback: Any) -> None:
        """Feedback as decoded (the core validates it; a goal sent with ``feedback_inline=True`` runs
        its callback within this call, on the driver's thread: it returns when the callback does, and
        a call that would wait for the driver's next answer raises ComponentError within it, see
        :func:`~agents_core.transport.goals.refuse_in_inline_feedback`)."""
        ...

    def status(self, status: GoalStatus) -> None:
        """A status change seen by the client."""
        ...

    def finished(self, status: GoalStatus, result: Any) -> None:
        """The goal ended (the core validates ``result``; only the first call counts).

        A driver that loses its server (gone, closed) calls it with ``GoalStatus.ABORTED`` and
        ``{"message": why}``, so that a client never waits for a result that cannot come.
        """
        ...

    def reject(self, reason: object) -> None:
        """Feedback, status or a result that did not decode, with why (counted)."""
        ...


@runtime_checkable
class DriverGoal(Protocol):
    """One sent goal as the driver tracks it (returned by :meth:`TransportDriver.send_goal`)."""

    #: Whether the server accepted the goal.
    accepted: bool
    #: Why the server rejected it (empty when accepted).
    reason: str

    def cancel(self, timeout: float) -> bool:
        """Ask the server to cancel the goal; whether it agreed."""
        ...

    def close(self) -> None:
        """Stop listening for the goal's events."""
        ...


# -- the base class: defaults for the optional primitives, capabilities derived ---------------------


def no_discovery_error(transport: str, driver: object) -> TransportError:
    """The error of ``discover()`` on a transport whose driver has no discovery primitive."""
    return TransportError(f"the {transport} transport does not support discovery "
                          f"(its driver {type(driver).__name__} has no discover())")


def no_goals_error(transport: str, what: str) -> TransportError:
    """The error of a goal call (``what``) on a transport whose driver has no goal primitives."""
    return TransportError(f"{what}: the {transport!r} transport has no long-running goals "
                          "(capabilities.actions is False)")


class DriverBase(TransportDriver):
    """Subclass this to write a driver: implement the required primitives, override the optional ones you can.

    The defaults (see :class:`TransportDriver` for what each primitive promises) say that the
    transport lacks the primitive; :attr:`capabilities` is derived from what the subclass
    overrides, once, when the class is created.
    """

    cross_process: bool = False
    discovery_settle_s: float = 1.0
    #: What this driver offers (set on every subclass by :func:`capabilities_of`; never declared by hand).
    capabilities: ClassVar[TransportCapabilities]

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls.capabilities = capabilities_of(cls)

    def discover(self, timeout: float) -> Graph:
        """Not supported: raises :class:`~agents_core.errors.TransportError`."""
        raise no_discovery_error(self.name, self)

    def serve_goals(self, name: str, definition: ActionType, hooks: GoalServerHooks, owner: str | None,
                    lane: Lane) -> DriverActionServer:
        """Not supported: raises :class:`~agents_core.errors.TransportError`."""
        raise no_goals_error(self.name, f"serve the action {name!r}")

    def send_goal(self, name: str, definition: ActionType, goal_id: str, goal: dict[str, Any],
                  events: GoalEvents, timeout: float) -> DriverGoal:
        """Not supported: raises :class:`~agents_core.errors.TransportError`."""
        raise no_goals_error(self.name, f"send a goal to {name!r}")

    def peer_process_options(self) -> dict[str, Any]:
        """``{}``: a peer process opens the transport with this one's options."""
        return {}


def _overrides(driver: object, primitive: str) -> bool:
    """Whether ``driver`` (a driver class or instance) has ``primitive`` other than :class:`DriverBase`'s default."""
    found = getattr(driver, primitive, None)
    return found is not None and getattr(found, "__func__", found) is not vars(DriverBase)[primitive]


def capabilities_of(driver: object) -> TransportCapabilities:
    """The capabilities of a driver (class or instance): derived from its primitives, with its declared data.

    ``actions``: it overrides both :meth:`~TransportDriver.serve_goals` and
    :meth:`~TransportDriver.send_goal`; ``discovery``: it overrides
    :meth:`~TransportDriver.discover`; ``cross_process``, ``discovery_settle_s``, ``local_requests``
    and ``validates_incoming``: its class attributes (default False, 1 s, False and False).
    """
    return TransportCapabilities(
        cross_process=bool(getattr(driver, "cross_process", False)),
        actions=_overrides(driver, "serve_goals") and _overrides(driver, "send_goal"),
        discovery=_overrides(driver, "discover"),
        discovery_settle_s=float(getattr(driver, "discovery_settle_s", 1.0)),
        local_requests=bool(getattr(driver, "local_requests", False)),
        validates_incoming=bool(getattr(driver, "validates_incoming", False)),
    )


DriverBase.capabilities = capabilities_of(DriverBase)
