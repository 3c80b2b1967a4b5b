"""agents_core: a transport-agnostic Physical-AI agent framework.

Compose an agent from components wired by typed topics, fired by triggers, calling models
through clients, reacting to events with actions; run the same recipe in memory, over Zenoh or
over ROS 2. This package imports no middleware: adapters load when a transport is asked for.
"""

from __future__ import annotations

from .actions import Action, component_action, component_fallback
from .components import Component, ComponentRunType, ModelComponent
from .config import BaseComponentConfig, ModelComponentConfig
from .errors import AgentsError
from .events import Event
from .launcher import Launcher
from .messages import Header
from .status import HealthStatus, LifecycleState
from .supported_types import SupportedType, add_additional_datatypes, get_type, registered_types
from .topics import FixedInput, QoSConfig, Topic
from .transport import MemoryTransport, Transport, resolve_transport

__version__ = "0.1.0"

__all__ = [
    "Action",
    "AgentsError",
    "BaseComponentConfig",
    "Component",
    "ComponentRunType",
    "Event",
    "FixedInput",
    "Header",
    "HealthStatus",
    "Launcher",
    "LifecycleState",
    "MemoryTransport",
    "ModelComponent",
    "ModelComponentConfig",
    "QoSConfig",
    "SupportedType",
    "Topic",
    "Transport",
    "__version__",
    "add_additional_datatypes",
    "component_action",
    "component_fallback",
    "get_type",
    "registered_types",
    "resolve_transport",
]
