"""The transport contract as its users see it: ``Transport`` and the handles it returns.

:class:`Transport` is :class:`~agents_core.transport.core.DriverTransport`, the one transport
(every middleware is a driver under it). What each primitive promises is specified once, on
:class:`~agents_core.transport.driver.TransportDriver`; what the core adds (validation, the closed
state, statistics, request lanes, status topics, delivery) is listed in
:mod:`agents_core.transport.core`. The protocols below name the handles a transport returns, for
annotations; what a transport offers beyond the required primitives is data
(:class:`TransportCapabilities`).
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

from ..status import HealthStatus, LifecycleState
from ..topics import Topic
from .core import DriverTransport
from .delivery import SubscriptionStatistics
from .driver import ServiceHandler, SubscriptionCallback, TransitionHandler, TransportCapabilities

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

#: The transport: every one is a :class:`~agents_core.transport.core.DriverTransport` around a driver.
Transport = DriverTransport


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

    def update(self, state: LifecycleState, health: HealthStatus, message: str = "", stats: str = "") -> None:
        """Show the component's current lifecycle state and health, and publish it on ``<name>/status``.

        ``stats``: the runtime's figures as compact JSON (:mod:`agents_core.runtime.figures`).
        """
        ...

    def close(self) -> None:
        """Withdraw the component (it disappears for observers); idempotent."""
        ...
