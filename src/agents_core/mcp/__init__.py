"""A running recipe over the Model Context Protocol (the ``mcp`` extra): actions as tools, topics as resources.

``launcher.enable_mcp()`` serves the recipe it launches; ``agentsctl mcp`` serves one running
elsewhere over stdio (what desktop AI clients start). See :mod:`agents_core.mcp.server`, and
:mod:`agents_core.guardrails` for what bounds every call.
"""

from __future__ import annotations

from .catalog import McpTool, RecipeCatalog, tool_name
from .server import DEFAULT_MCP_PORT, McpBridge, McpHttpServer

__all__ = ["DEFAULT_MCP_PORT", "McpBridge", "McpHttpServer", "McpTool", "RecipeCatalog", "tool_name"]
