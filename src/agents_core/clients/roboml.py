"""RoboML: the names of its protocol module and of its three clients, importable from one place.

The protocol itself (routes, frames, commands, the msgpack-numpy format) is described and
implemented in :mod:`agents_core.clients.roboml_protocol`; the clients live in
:mod:`~agents_core.clients.roboml_http`, :mod:`~agents_core.clients.roboml_ws` and
:mod:`~agents_core.clients.roboml_resp`. Each of those imports the protocol module, never this
one, so importing the clients from here (as upstream's ``agents.clients.roboml`` allows) makes no
import cycle.
"""

from __future__ import annotations

from . import roboml_protocol
from .roboml_http import RoboMLHTTPClient
from .roboml_protocol import *  # noqa: F403  # every protocol name, importable here as before the split
from .roboml_resp import RoboMLRESPClient
from .roboml_ws import RoboMLWSClient

__all__ = ["RoboMLHTTPClient", "RoboMLRESPClient", "RoboMLWSClient"]
__all__ += roboml_protocol.__all__
