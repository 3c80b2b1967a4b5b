"""The tools of ``CortexConfig.mcp_servers`` for the Cortex planner (the ``mcp`` extra).

The connections are the LLM's (:mod:`agents_core.mcp.client`): at configure the Cortex connects
to each server, lists its tools and offers each to the planner as ``<server name>__<tool name>``
(kind ``"mcp"``, a plan step; a research tool when named in ``planning_tools``). A call goes
through the tool's guardrails (allow-list, limits, approval, rate limit, audit) like an action's,
after the planner's own schema check; a server that hangs or dies fails that step, saying so.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

from .tools import Tool, ToolBox

__all__ = ["call_mcp_tool", "connect_mcp_servers", "disconnect_mcp_servers"]


def connect_mcp_servers(servers: Sequence[Any], tools: ToolBox, planning_tools: Sequence[str],
                        logger: logging.Logger) -> list[Any]:
    """Connect to ``servers`` and add their tools to ``tools``; the open connections (to close later)."""
    if not servers:
        return []
    from ...mcp.client import open_toolboxes  # noqa: PLC0415  (the mcp extra, only when servers are given)

    boxes = open_toolboxes(servers)
    try:
        for box in boxes:
            _offer(box, tools, planning_tools, logger)
    except BaseException:  # a listing that failed (too large, timed out): no connection is left open
        disconnect_mcp_servers(boxes, tools)
        raise
    return boxes


def _offer(box: Any, tools: ToolBox, planning_tools: Sequence[str], logger: logging.Logger) -> None:
    offered = 0
    for remote in box.tools():
        function: dict[str, Any] = remote.description["function"]
        if tools.add(Tool(name=remote.__name__, kind="mcp", description=str(function["description"])
                          or remote.remote_name, parameters=dict(function["parameters"]), component=None,
                          target=remote.remote_name, planning=remote.__name__ in planning_tools,
                          action=remote), replace=False):
            offered += 1
        else:
            logger.warning("MCP server %r: tool %r clashes with a tool already offered; not offered",
                           box.spec.name, remote.__name__)
    logger.info("MCP server %r: %d tool(s) offered to the planner", box.spec.name, offered)


def disconnect_mcp_servers(boxes: Sequence[Any], tools: ToolBox) -> None:
    """Take the servers' tools out of ``tools`` and close the connections."""
    for box in boxes:
        tools.remove_where(lambda tool, box=box: tool.kind == "mcp" and getattr(tool.action, "_box", None) is box)
        box.close()


def call_mcp_tool(tool: Tool, arguments: dict[str, Any]) -> str:
    """Run an ``"mcp"`` tool (through its guardrails, as the caller ``cortex``); its result's text."""
    from ...guardrails import with_caller  # noqa: PLC0415

    with with_caller("cortex"):
        return str(tool.action(**arguments))
