"""Transports: the one transport on a middleware driver, the driver contract, the in-memory one, lookup, goals."""

from __future__ import annotations

from .contract import (
    ActionServer,
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
from .core import DriverTransport
from .delivery import BoundedDelivery, SubscriptionStatistics
from .descriptor import TransportDescriptor
from .driver import DriverBase, TransportDriver
from .goals import ActionType, FieldSpec, GoalClient, GoalHandle, GoalStatus, register_action_type
from .graph import Graph, TopicInfo, describe_component
from .memory import MemoryTransport, TopicStatistics
from .registry import (
    ENTRY_POINT_GROUP,
    TRANSPORT_ALIASES,
    available_transports,
    describe_transport_kind,
    register_transport,
    resolve_transport,
)

__all__ = [
    "ENTRY_POINT_GROUP",
    "TRANSPORT_ALIASES",
    "ActionServer",
    "ActionType",
    "BoundedDelivery",
    "ComponentPresence",
    "DriverBase",
    "DriverTransport",
    "FieldSpec",
    "GoalClient",
    "GoalHandle",
    "GoalStatus",
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
    "TransportDescriptor",
    "TransportDriver",
    "available_transports",
    "describe_component",
    "describe_transport_kind",
    "register_action_type",
    "register_transport",
    "resolve_transport",
]
