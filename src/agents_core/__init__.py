"""agents_core: a transport-agnostic Physical-AI agent framework.

Compose an agent from components wired by typed topics, fired by triggers, calling models
through clients, reacting to events with actions; run the same recipe in memory, over Zenoh or
over ROS 2. This package imports no middleware: adapters load when a transport is asked for.

``import agents_core`` imports nothing else either: each name below is imported from its module on
first use (PEP 562), so a process that only relays topics never loads the model stack.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .support.lazy import keep_moved_modules, lazy_facade

# The package root holds the user's vocabulary, machinery lives in folders (support/, declarations/);
# a module that moved keeps its old import path (a plugin or a recipe may import it by that one).
keep_moved_modules({f"{__name__}.{old}": f"{__name__}.{new}" for old, new in (
    ("_lazy", "support.lazy"), ("_numpy", "support.lazy_numpy"), ("_version", "support.version"),
    ("bounded_json", "support.bounded_json"), ("checked_attrs", "support.checked_attrs"),
    ("concurrency", "support.concurrency"), ("console", "support.console"), ("install_hint", "support.install_hint"),
    ("registry", "support.registry"), ("action_schema", "declarations.action_schema"),
    ("component_method", "declarations.component_method"), ("event_transfer", "declarations.event_transfer"),
    ("setup_calls", "declarations.setup_calls"))})

if TYPE_CHECKING:
    from .actions import Action as Action
    from .actions import component_action as component_action
    from .actions import component_fallback as component_fallback
    from .components import Component as Component
    from .components import ComponentRunType as ComponentRunType
    from .components import ModelComponent as ModelComponent
    from .config import BaseComponentConfig as BaseComponentConfig
    from .config import ModelComponentConfig as ModelComponentConfig
    from .errors import AgentsError as AgentsError
    from .events import Event as Event
    from .launch.launcher import Launcher as Launcher
    from .messages import Header as Header
    from .status import HealthStatus as HealthStatus
    from .status import LifecycleState as LifecycleState
    from .supported_types import SupportedType as SupportedType
    from .supported_types import add_additional_datatypes as add_additional_datatypes
    from .supported_types import get_type as get_type
    from .supported_types import registered_types as registered_types
    from .topics import FixedInput as FixedInput
    from .topics import QoSConfig as QoSConfig
    from .topics import Topic as Topic
    from .transport import MemoryTransport as MemoryTransport
    from .transport import Transport as Transport
    from .transport import resolve_transport as resolve_transport
else:
    _lazy_getattr, __dir__ = lazy_facade(__name__, own=("__version__",))

    def __getattr__(name: str) -> Any:
        if name == "__version__":
            from .support.version import package_version  # noqa: PLC0415

            value = globals()["__version__"] = package_version()
            return value
        return _lazy_getattr(name)

#: The version of this package: pyproject.toml's, read on first access (``_version``); declared, not
#: assigned, so that the module ``__getattr__`` above answers it.
__version__: str
