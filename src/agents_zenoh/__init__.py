"""The Zenoh adapter for agents_core (install with ``pip install 'agents-core[zenoh]'``).

Importing this package does not import ``zenoh``; :mod:`agents_zenoh.transport` does (it is
what ``Launcher(transport="zenoh")`` loads). The wire format a third-party Zenoh client needs
is documented in ``docs/zenoh-wire-format.md``.

- :class:`ZenohConfig`: session settings (mode, endpoints, namespace, scouting, ...).
- :class:`ZenohTransport`: the transport (loaded on first access).
- :func:`register_codec`: teach the adapter a message type you registered yourself.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .codecs import CodecError, describe_schemas, register_codec
from .config import ZenohConfig

if TYPE_CHECKING:
    from .transport import ZenohTransport

__all__ = ["CodecError", "ZenohConfig", "ZenohTransport", "describe_schemas", "register_codec"]


def __getattr__(name: str) -> Any:
    # ZenohTransport imports zenoh; load it only when asked for.
    if name == "ZenohTransport":
        return importlib.import_module(".transport", __name__).ZenohTransport
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
