"""The driver contract: the few primitives a middleware adapter implements.

A middleware adapter is a *driver*. :class:`~agents_core.transport.core.DriverTransport` puts the
public :class:`~agents_core.transport.contract.Transport` surface on top of any driver and keeps
everything else in one place: validation against the topic's type, the closed state, duplicate
names, one type per topic, statistics, the request lanes (one per component), the caller's
deadline, the status topic of each component, and the delivery of received values (a thread for
user callbacks, straight to the component's worker for component inputs).

A driver implements :class:`TransportDriver`, seven methods:

1. :meth:`~TransportDriver.open_publisher`: send already validated values of one topic;
2. :meth:`~TransportDriver.open_subscriber`: decode what arrives on one topic and hand each value
   to the :class:`Sink` the core gives it (``sink.offer(value)``) or report a payload that does
   not decode (``sink.reject(reason)``); both return at once and never raise, so calling them on
   the middleware's own thread is right;
3. :meth:`~TransportDriver.serve`: answer requests on a name; each request is run through
   ``lane(job)`` (the owner's request lane), where ``job()`` calls ``handler`` and replies;
4. :meth:`~TransportDriver.call`: send one request and wait for its reply;
5. :meth:`~TransportDriver.declare_presence`: make a component visible with its lifecycle state
   and health, and route transitions asked from outside through ``lane``;
6. :meth:`~TransportDriver.observe`: read another component's state, or ask it for a transition,
   as an outside tool would;
7. :meth:`~TransportDriver.close`.

One primitive is optional: a driver that can see the whole graph (every topic with its type and
how many publishers and subscribers it has, and the live components) also implements
:class:`DiscoveringDriver` (``discover(timeout) -> Graph``). Without it,
:meth:`DriverTransport.discover() <agents_core.transport.core.DriverTransport.discover>` raises
a :class:`~agents_core.errors.TransportError` saying the transport does not support discovery.
A driver that carries long-running goals also implements :class:`ActionDriver` (two more
methods, :meth:`~ActionDriver.serve_goals` and :meth:`~ActionDriver.send_goal`) and says so with
``capabilities.actions=True``. The core keeps the goal bookkeeping (validation, goal ids, the
thread of each goal, status changes, results kept for late result requests, the closed state;
see :mod:`agents_core.transport.goal_serving`); the driver only carries goals, cancels,
feedback, status and results between the two sides.

Errors: a driver raises the core's errors (:class:`~agents_core.errors.RequestTimeoutError`,
:class:`~agents_core.errors.ServiceUnavailableError`, :class:`~agents_core.errors.RemoteError`,
:class:`~agents_core.errors.TransportError`), mapping its middleware's own.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

from ..messages import ComponentStatusMsg
from ..status import HealthStatus, LifecycleState
from ..topics import Topic
from .contract import ServiceHandler, TransitionHandler, TransportCapabilities
from .goals import ActionType, GoalStatus
from .graph import Graph

__all__ = [
    "ActionDriver",
    "Closable",
    "DiscoveringDriver",
    "DriverActionServer",
    "DriverGoal",
    "DriverPresence",
    "DriverPublisher",
    "GoalEvents",
    "GoalServerHooks",
    "Lane",
    "Sink",
    "TransportDriver",
]

#: Runs a job on the request lane of the owner of a service or component (never blocks).
Lane = Callable[[Callable[[], None]], None]


@runtime_checkable
class Sink(Protocol):
    """Where a driver hands what it receives on one topic (given by the core)."""

    def offer(self, value: Any) -> None:
        """A decoded value (not yet validated: the core validates it). Never blocks, never raises."""
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
    """A middleware adapter's primitives (see the module docstring)."""

    #: The name the transport is resolved by ("memory", "zenoh", "ros2", or a third party's).
    name: str
    capabilities: TransportCapabilities

    def open_publisher(self, topic: Topic, owner: str | None) -> DriverPublisher:
        """A publisher for ``topic`` (``owner``: the component it belongs to, if any)."""
        ...

    def open_subscriber(self, topic: Topic, sink: Sink, owner: str | None) -> Closable:
        """Hand what arrives on ``topic`` to ``sink`` until closed."""
        ...

    def serve(self, name: str, handler: ServiceHandler, owner: str | None, lane: Lane) -> Closable:
        """Answer requests on ``name``: run ``handler`` through ``lane`` and send back its reply or error."""
        ...

    def call(self, name: str, payload: dict[str, Any], timeout: float) -> dict[str, Any]:
        """Send ``payload`` to the service ``name``; its reply, or the errors listed in the module docstring."""
        ...

    def declare_presence(self, name: str, on_transition: TransitionHandler, lane: Lane) -> DriverPresence:
        """Make component ``name`` visible; transitions asked from outside run ``on_transition`` via ``lane``."""
        ...

    def observe(self, name: str, transition: str | None, timeout: float) -> ComponentStatusMsg | bool | None:
        """With ``transition`` None: component ``name``'s state as an observer reads it (None if absent).

        Otherwise ask it for ``transition`` as an outside tool would, and return whether it was done.
        """
        ...

    def close(self) -> None:
        """Release the session, nodes and threads; the core has closed every handle before."""
        ...


@runtime_checkable
class DiscoveringDriver(Protocol):
    """The optional discovery primitive (see the module docstring)."""

    def discover(self, timeout: float) -> Graph:
        """Every topic (name, type, publisher and subscriber counts) and live component this driver sees.

        Waits at most ``timeout`` seconds for the middleware's discovery to settle; what was not
        seen by then is not in the graph.
        """
        ...


# -- long-running goals (optional: drivers with capabilities.actions=True) -------------------------


@runtime_checkable
class GoalServerHooks(Protocol):
    """What the core gives a driver's action server; every method is safe on any thread."""

    def on_goal(self, goal_id: str, goal: Any) -> str | None:
        """A goal arrived (decoded, not yet validated): None if accepted, else why it was rejected.

        May run the server's ``accept`` callback (user code): call it through the lane given to
        :meth:`ActionDriver.serve_goals` where the middleware's thread must not wait. Never raises.
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
    """Carries one action server's goal events to its clients (returned by :meth:`ActionDriver.serve_goals`)."""

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
        """Feedback as decoded (the core validates it)."""
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
    """One sent goal as the driver tracks it (returned by :meth:`ActionDriver.send_goal`)."""

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


@runtime_checkable
class ActionDriver(Protocol):
    """The two primitives of a driver that carries long-running goals (``capabilities.actions``)."""

    def serve_goals(self, name: str, definition: ActionType, hooks: GoalServerHooks, owner: str | None,
                    lane: Lane) -> DriverActionServer:
        """Serve goals of ``definition`` on ``name``: hand goals, cancels and result requests to ``hooks``."""
        ...

    def send_goal(self, name: str, definition: ActionType, goal_id: str, goal: dict[str, Any],
                  events: GoalEvents, timeout: float) -> DriverGoal:
        """Send a goal and wait (up to ``timeout``) for its acceptance; then feed ``events`` until it ends.

        Raises :class:`~agents_core.errors.ServiceUnavailableError` when nobody serves ``name``
        within ``timeout`` and :class:`~agents_core.errors.RequestTimeoutError` when the server
        does not answer in time.
        """
        ...
