"""The Zenoh adapter for agents_core (install with ``pip install 'agents-core[zenoh]'``).

Importing this package does not import ``zenoh``; :mod:`agents_zenoh.transport` does (it is
what ``Launcher(transport="zenoh")`` loads). The wire format a third-party Zenoh client needs
is documented in ``docs/zenoh-wire-format.md``.

- :class:`ZenohConfig`: session settings (mode, endpoints, namespace, scouting, ...).
- :class:`ZenohTransport`: the transport (loaded on first access).
- :func:`register_codec`: teach the adapter a message type you registered yourself.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from agents_core.support.lazy import lazy_facade

from .codecs import CodecError as CodecError
from .codecs import describe_schemas as describe_schemas
from .codecs import register_codec as register_codec
from .config import ZenohConfig as ZenohConfig

if TYPE_CHECKING:
    # ZenohTransport imports zenoh: loaded on first access.
    from .transport import ZenohTransport as ZenohTransport
else:
    __getattr__, __dir__ = lazy_facade(__name__)
