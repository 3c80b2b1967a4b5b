"""agents_core: a transport-agnostic Physical-AI agent framework.

Compose an agent from components wired by typed topics, fired by triggers, calling models
through clients, reacting to events with actions; run the same recipe in memory, over Zenoh or
over ROS 2. This package imports no middleware: adapters load when a transport is asked for.

``import agents_core`` imports nothing else either: each name below is imported from its module on
first use (PEP 562), so a process that only relays topics never loads the model stack.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ._lazy import lazy_facade

if TYPE_CHECKING:
    from .actions import Action, component_action, component_fallback
    from .components import Component, ComponentRunType, ModelComponent
    from .config import BaseComponentConfig, ModelComponentConfig
    from .errors import AgentsError
    from .events import Event
    from .launch.launcher import Launcher
    from .messages import Header
    from .status import HealthStatus, LifecycleState
    from .supported_types import SupportedType, add_additional_datatypes, get_type, registered_types
    from .topics import FixedInput, QoSConfig, Topic
    from .transport import MemoryTransport, Transport, resolve_transport
else:
    _lazy_getattr, _lazy_dir = lazy_facade(__name__)

    def __dir__() -> list[str]:
        return sorted({*_lazy_dir(), "__version__"})

    def __getattr__(name: str) -> Any:
        if name == "__version__":
            from ._version import package_version  # noqa: PLC0415

            value = globals()["__version__"] = package_version()
            return value
        return _lazy_getattr(name)

#: The version of this package: pyproject.toml's, read on first access (``_version``); declared, not
#: assigned, so that the module ``__getattr__`` above answers it.
__version__: str

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
