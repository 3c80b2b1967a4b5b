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
from .graph import Graph

__all__ = [
    "Closable",
    "DiscoveringDriver",
    "DriverPresence",
    "DriverPublisher",
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
