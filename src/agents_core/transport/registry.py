"""Finding a transport by name: built-in aliases, then the ``agents_core.transports`` entry points.

Adapters are imported only when asked for, so ``import agents_core`` works with no middleware
installed. A missing dependency becomes a :class:`~agents_core.errors.TransportNotAvailableError`
that names the pip extra to install; a typo gets a "did you mean".

A third-party package registers its driver (a :class:`~agents_core.transport.driver.DriverBase`
subclass) in its ``pyproject.toml``::

    [project.entry-points."agents_core.transports"]
    mqtt = "my_package.transport:MqttDriver"

The object the entry point loads is called with the keyword options given to
:func:`resolve_transport` and returns a driver (wrapped in a
:class:`~agents_core.transport.core.DriverTransport`) or a ready transport. It may instead be a
:class:`~agents_core.transport.descriptor.TransportDescriptor` (whose ``factory`` builds the
transport), or carry one as its ``descriptor`` attribute: that is what the CLI, the UI, the
launcher and the test harness ask about the transport (:func:`describe_transport_kind`). A
transport given no descriptor is taken for a cross-process one that takes no endpoints.
:func:`register_transport` does the same from code (a test, an application that brings its own).

This module is the one place that knows transports by name.
"""

from __future__ import annotations

import difflib
import importlib
import os
from typing import Any

from ..errors import ConfigError, TransportNotAvailableError
from ..support.install_hint import install_hint
from .contract import Transport
from .descriptor import TransportDescriptor
from .driver import DriverBase

__all__ = ["DEFAULT_CROSS_PROCESS", "ENTRY_POINT_GROUP", "TRANSPORT_ALIASES", "available_transports",
           "cross_process_transports", "describe_transport_kind", "descriptor_of", "known_transports",
           "register_transport", "resolve_transport"]

ENTRY_POINT_GROUP = "agents_core.transports"

#: name -> ("module:attribute", the pip extra that provides its dependencies or None)
TRANSPORT_ALIASES: dict[str, tuple[str, str | None]] = {
    "memory": ("agents_core.transport.memory:MemoryTransport", None),
    "zenoh": ("agents_zenoh.transport:ZenohTransport", "zenoh"),
    "ros2": ("agents_ros2.transport:Ros2Transport", "ros2"),
    "rmw_zenoh": ("agents_zenoh.rmw.transport:RmwZenohTransport", "rmw-zenoh"),
}

#: name -> ``"module:attribute"`` of the built-in transports' descriptors (none of them imports its middleware).
BUILTIN_DESCRIPTORS: dict[str, str] = {
    "memory": "agents_core.transport.descriptor:MEMORY",
    "zenoh": "agents_zenoh.descriptor:DESCRIPTOR",
    "ros2": "agents_ros2.descriptor:DESCRIPTOR",
    "rmw_zenoh": "agents_zenoh.rmw.descriptor:DESCRIPTOR",
}

#: The cross-process transport chosen when one is needed and none is named (CLI observers, multiprocessing).
DEFAULT_CROSS_PROCESS = "zenoh"

#: Transports registered from code (:func:`register_transport`), by name.
_registered: dict[str, tuple[TransportDescriptor, Any]] = {}

#: Environment variable read when no transport is named.
TRANSPORT_ENV_VAR = "AGENTS_TRANSPORT"


def _entry_point_names() -> dict[str, Any]:
    # Imported here: importlib.metadata costs tens of milliseconds, and most processes resolve
    # a built-in transport by its alias without ever needing it.
    from importlib.metadata import entry_points  # noqa: PLC0415

    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def available_transports() -> list[str]:
    """Every name :func:`resolve_transport` knows (built-in, registered and installed third-party)."""
    return sorted(set(TRANSPORT_ALIASES) | set(_registered) | set(_entry_point_names()))


def known_transports() -> list[str]:
    """:func:`available_transports`, the built-in ones first (in their order), then the others sorted."""
    return [*TRANSPORT_ALIASES, *(name for name in available_transports() if name not in TRANSPORT_ALIASES)]


def register_transport(descriptor: TransportDescriptor, factory: Any = None) -> TransportDescriptor:
    """Make ``descriptor.name`` resolvable in this process (``factory``: what builds it; None: ``descriptor.factory``).

    Other processes (a component process, ``agentsctl``) know it through an entry point instead.
    """
    if not isinstance(descriptor, TransportDescriptor):
        raise ConfigError(f"register_transport takes a TransportDescriptor, got {type(descriptor).__name__}")
    name = descriptor.name.strip().lower()
    if name in TRANSPORT_ALIASES:
        raise ConfigError(f"{name!r} is a built-in transport; register yours under another name")
    _registered[name] = (descriptor, factory)
    return descriptor


def _load_target(target: str) -> Any:
    module_name, _, attr = target.partition(":")
    obj: Any = importlib.import_module(module_name)
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


def _default_descriptor(name: str, factory: str, extra: str | None = None) -> TransportDescriptor:
    return TransportDescriptor(name=name, factory=factory, extra=extra,
                               carries=frozenset({"values", "requests", "cross-process", "attach"}))


def describe_transport_kind(name: str | None = None) -> TransportDescriptor:
    """The descriptor of transport ``name`` (None: :data:`TRANSPORT_ENV_VAR`, default ``"memory"``).

    Built-in descriptors are read without importing the middleware; a third party's entry point is
    loaded. TransportNotAvailableError (with a "did you mean") for a name nobody registered.
    """
    name = (name if name is not None else os.environ.get(TRANSPORT_ENV_VAR, "").strip() or "memory").strip().lower()
    if name in _registered:
        return _registered[name][0]
    if name in TRANSPORT_ALIASES:
        if name in BUILTIN_DESCRIPTORS:
            found = _load_target(BUILTIN_DESCRIPTORS[name])
            if isinstance(found, TransportDescriptor):
                return found
        target, extra = TRANSPORT_ALIASES[name]
        return _default_descriptor(name, target, extra)
    eps = _entry_point_names()
    if name not in eps:
        raise _unknown(name)
    loaded = eps[name].load()
    if isinstance(loaded, TransportDescriptor):
        return loaded
    found = getattr(loaded, "descriptor", None)
    if isinstance(found, TransportDescriptor):
        return found
    return _default_descriptor(name, str(eps[name].value))


def descriptor_of(transport: Transport | Any) -> TransportDescriptor:
    """The descriptor of an open transport (by the name it was resolved by); a default one if nobody registered it."""
    name = str(getattr(transport, "name", type(transport).__name__))
    try:
        return describe_transport_kind(name)
    except TransportNotAvailableError:
        return _default_descriptor(name, f"{type(transport).__module__}:{type(transport).__qualname__}")


def cross_process_transports() -> list[str]:
    """The transports installed here whose descriptors say ``cross-process``: built-in first, in their order."""
    names = []
    for name in known_transports():
        try:
            descriptor = describe_transport_kind(name)
        except Exception:  # a broken third-party registration: not offered
            continue
        if descriptor.cross_process and descriptor.missing_module() is None:
            names.append(name)
    return names


def _unknown(spec: str) -> TransportNotAvailableError:
    known = available_transports()
    close = difflib.get_close_matches(spec.strip().lower(), known, n=2, cutoff=0.5)
    hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
    return TransportNotAvailableError(f"unknown transport {spec!r}{hint} (known: {', '.join(known)})")


def _load_alias(name: str) -> Any:
    target, extra = TRANSPORT_ALIASES[name]
    module_name, _, attr = target.partition(":")
    try:
        module = importlib.import_module(module_name)
    except TransportNotAvailableError:
        raise  # the adapter already said precisely what is missing
    except ImportError as exc:
        if extra is None:
            raise
        raise TransportNotAvailableError(
            f"the {name!r} transport needs the '{extra}' extra ({exc}); install it with: "
            f"{install_hint(extra)}"
        ) from exc
    return getattr(module, attr)


def resolve_transport(spec: str | Transport | None = None, **options: Any) -> Transport:
    """Return a ready transport for ``spec``.

    ``spec`` is a transport object (returned as is), a name (``"memory"``, ``"zenoh"``,
    ``"ros2"`` or an entry point's), or None to read :data:`TRANSPORT_ENV_VAR` (default
    ``"memory"``). ``options`` go to the transport's constructor.
    """
    if spec is None:
        spec = os.environ.get(TRANSPORT_ENV_VAR, "").strip() or "memory"
    if not isinstance(spec, str):
        if isinstance(spec, Transport):
            if options:
                raise ConfigError("transport options are only accepted with a transport name")
            return spec
        raise ConfigError(f"transport must be a name or a Transport, got {type(spec).__name__}")
    name = spec.strip().lower()
    if name in _registered:
        descriptor, factory = _registered[name]
        if factory is None:
            factory = descriptor.load_factory()
    elif name in TRANSPORT_ALIASES:
        factory = _load_alias(name)
    else:
        eps = _entry_point_names()
        if name not in eps:
            raise _unknown(spec)
        factory = eps[name].load()
        if isinstance(factory, TransportDescriptor):
            factory = factory.load_factory()
    transport = factory(**options)
    if isinstance(transport, DriverBase):
        transport = Transport(transport)
    if not isinstance(transport, Transport):
        raise TransportNotAvailableError(f"transport {name!r} does not implement the Transport contract")
    return transport
