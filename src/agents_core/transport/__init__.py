"""Transports: the one transport on a middleware driver, the driver contract, the in-memory one, lookup, goals."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..support.lazy import lazy_facade
from .contract import ActionServer as ActionServer
from .contract import ComponentPresence as ComponentPresence
from .contract import Publisher as Publisher
from .contract import ServiceHandler as ServiceHandler
from .contract import ServiceServer as ServiceServer
from .contract import Subscription as Subscription
from .contract import SubscriptionCallback as SubscriptionCallback
from .contract import TransitionHandler as TransitionHandler
from .contract import Transport as Transport
from .contract import TransportCapabilities as TransportCapabilities
from .core import DriverTransport as DriverTransport
from .delivery import BoundedDelivery as BoundedDelivery
from .delivery import SubscriptionStatistics as SubscriptionStatistics
from .descriptor import TransportDescriptor as TransportDescriptor
from .driver import DriverBase as DriverBase
from .driver import TransportDriver as TransportDriver
from .goals import ActionType as ActionType
from .goals import FieldSpec as FieldSpec
from .goals import GoalClient as GoalClient
from .goals import GoalHandle as GoalHandle
from .goals import GoalStatus as GoalStatus
from .goals import register_action_type as register_action_type
from .graph import Graph as Graph
from .graph import TopicInfo as TopicInfo
from .graph import describe_component as describe_component
from .memory import MemoryTransport as MemoryTransport
from .memory import TopicStatistics as TopicStatistics
from .registry import ENTRY_POINT_GROUP as ENTRY_POINT_GROUP
from .registry import TRANSPORT_ALIASES as TRANSPORT_ALIASES
from .registry import available_transports as available_transports
from .registry import describe_transport_kind as describe_transport_kind
from .registry import register_transport as register_transport
from .registry import resolve_transport as resolve_transport

if not TYPE_CHECKING:
    __getattr__, __dir__ = lazy_facade(__name__)
