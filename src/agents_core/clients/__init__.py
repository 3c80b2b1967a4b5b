"""Clients for model serving platforms and vector databases.

Each name is imported from its module on first use (PEP 562), so using one client does not load
the others (nor httpx for a process that uses none). To add a client, add its module and names to
``_EXPORTS``, to the ``TYPE_CHECKING`` imports and to ``__all__`` (tests/test_import_cost.py checks
that the three agree).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_facade

#: Clients register themselves by class name when their module is imported, and these names read that
#: registry (ChromaClient rebuilds its embedding client from a spec): taking one from the package imports
#: every built-in client first, as the eager package did.
_NEED_EVERY_CLIENT = ("client_from_spec", "client_types")

if TYPE_CHECKING:
    from .chroma.client import ChromaClient
    from .client_base import BaseClient, client_from_spec, client_types
    from .db_base import DBClient
    from .generic import GenericHTTPClient
    from .lerobot.client import LeRobotClient
    from .model_base import ModelClient
    from .ollama import OllamaClient
    from .policy_base import PolicyClient
    from .roboml_http import RoboMLHTTPClient
    from .roboml_resp import RoboMLRESPClient
    from .roboml_ws import RoboMLWSClient
else:
    __getattr__, __dir__ = lazy_facade(__name__, import_all_for=_NEED_EVERY_CLIENT)

__all__ = ["BaseClient", "ChromaClient", "DBClient", "GenericHTTPClient", "LeRobotClient", "ModelClient",
           "OllamaClient", "PolicyClient", "RoboMLHTTPClient", "RoboMLRESPClient", "RoboMLWSClient",
           "client_from_spec", "client_types"]
