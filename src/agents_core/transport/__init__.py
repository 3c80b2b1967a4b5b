"""Transports: the contract every middleware adapter implements, the in-memory one, and lookup by name."""

from __future__ import annotations

from .contract import (
    ComponentPresence,
    Publisher,
    ServiceHandler,
    ServiceServer,
    Subscription,
    SubscriptionCallback,
    TransitionHandler,
    Transport,
    TransportCapabilities,
)
from .delivery import BoundedDelivery, SubscriptionStatistics
from .graph import Graph, TopicInfo, describe_component
from .memory import MemoryTransport, TopicStatistics
from .registry import ENTRY_POINT_GROUP, TRANSPORT_ALIASES, available_transports, resolve_transport

__all__ = [
    "ENTRY_POINT_GROUP",
    "TRANSPORT_ALIASES",
    "BoundedDelivery",
    "ComponentPresence",
    "Graph",
    "MemoryTransport",
    "Publisher",
    "ServiceHandler",
    "ServiceServer",
    "Subscription",
    "SubscriptionCallback",
    "SubscriptionStatistics",
    "TopicInfo",
    "TopicStatistics",
    "TransitionHandler",
    "Transport",
    "TransportCapabilities",
    "available_transports",
    "describe_component",
    "resolve_transport",
]
