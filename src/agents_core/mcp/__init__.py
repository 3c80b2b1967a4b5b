"""A running recipe over the Model Context Protocol (the ``mcp`` extra): actions as tools, topics as resources.

``launcher.enable_mcp()`` serves the recipe it launches; ``agentsctl mcp`` serves one running
elsewhere over stdio (what desktop AI clients start). See :mod:`agents_core.mcp.server`, and
:mod:`agents_core.guardrails` for what bounds every call.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..support.lazy import lazy_facade
from .catalog import McpTool as McpTool
from .catalog import RecipeCatalog as RecipeCatalog
from .catalog import tool_name as tool_name
from .server import DEFAULT_MCP_PORT as DEFAULT_MCP_PORT
from .server import McpBridge as McpBridge
from .server import McpHttpServer as McpHttpServer

if not TYPE_CHECKING:
    __getattr__, __dir__ = lazy_facade(__name__)
