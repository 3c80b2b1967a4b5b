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
:class:`~agents_core.transport.core.DriverTransport`) or a ready transport.
"""

from __future__ import annotations

import difflib
import importlib
import os
from typing import Any

from ..errors import ConfigError, TransportNotAvailableError
from ..install_hint import install_hint
from .contract import Transport
from .driver import DriverBase

__all__ = ["ENTRY_POINT_GROUP", "TRANSPORT_ALIASES", "available_transports", "resolve_transport"]

ENTRY_POINT_GROUP = "agents_core.transports"

#: name -> ("module:attribute", the pip extra that provides its dependencies or None)
TRANSPORT_ALIASES: dict[str, tuple[str, str | None]] = {
    "memory": ("agents_core.transport.memory:MemoryTransport", None),
    "zenoh": ("agents_zenoh.transport:ZenohTransport", "zenoh"),
    "ros2": ("agents_ros2.transport:Ros2Transport", "ros2"),
}

#: Environment variable read when no transport is named.
TRANSPORT_ENV_VAR = "AGENTS_TRANSPORT"


def _entry_point_names() -> dict[str, Any]:
    # Imported here: importlib.metadata costs tens of milliseconds, and most processes resolve
    # a built-in transport by its alias without ever needing it.
    from importlib.metadata import entry_points  # noqa: PLC0415

    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def available_transports() -> list[str]:
    """Every name :func:`resolve_transport` knows (built-in and installed third-party)."""
    return sorted(set(TRANSPORT_ALIASES) | set(_entry_point_names()))


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
    if name in TRANSPORT_ALIASES:
        factory = _load_alias(name)
    else:
        eps = _entry_point_names()
        if name not in eps:
            known = available_transports()
            close = difflib.get_close_matches(name, known, n=2, cutoff=0.5)
            hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
            raise TransportNotAvailableError(
                f"unknown transport {spec!r}{hint} (known: {', '.join(known)})"
            )
        factory = eps[name].load()
    transport = factory(**options)
    if isinstance(transport, DriverBase):
        transport = Transport(transport)
    if not isinstance(transport, Transport):
        raise TransportNotAvailableError(f"transport {name!r} does not implement the Transport contract")
    return transport
