"""Clients for model serving platforms and vector databases.

Each name is imported from its module on first use (PEP 562), so using one client does not load
the others (nor httpx for a process that uses none). To add a client, add one line per name under
``if TYPE_CHECKING:`` below (``from .mine import MineClient as MineClient``): that line is the whole
re-export (see :mod:`agents_core.support.lazy`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..support.lazy import lazy_facade

#: Clients register themselves by class name when their module is imported, and these names read that
#: registry (ChromaClient rebuilds its embedding client from a spec): taking one from the package imports
#: every built-in client first, as the eager package did.
_NEED_EVERY_CLIENT = ("client_from_spec", "client_types")

if TYPE_CHECKING:
    from .chroma.client import ChromaClient as ChromaClient
    from .client_base import BaseClient as BaseClient
    from .client_base import client_from_spec as client_from_spec
    from .client_base import client_types as client_types
    from .db_base import DBClient as DBClient
    from .generic import GenericHTTPClient as GenericHTTPClient
    from .lerobot.client import LeRobotClient as LeRobotClient
    from .model_base import ModelClient as ModelClient
    from .ollama import OllamaClient as OllamaClient
    from .policy_base import PolicyClient as PolicyClient
    from .roboml_http import RoboMLHTTPClient as RoboMLHTTPClient
    from .roboml_resp import RoboMLRESPClient as RoboMLRESPClient
    from .roboml_ws import RoboMLWSClient as RoboMLWSClient
else:
    __getattr__, __dir__ = lazy_facade(__name__, import_all_for=_NEED_EVERY_CLIENT)
