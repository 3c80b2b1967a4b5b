"""The recipe most MCP tests serve: the Arm of :mod:`tests.mcp.mcp_parts` on memory, over Streamable HTTP."""

from __future__ import annotations

import pytest

from agents_core import Launcher

from .mcp_parts import MOTION, arm


@pytest.fixture
def served(tmp_path):
    pytest.importorskip("mcp", reason="the mcp extra is not installed")
    from agents_core.mcp import McpBridge  # noqa: PLC0415  (the mcp extra)

    component = arm()
    launcher = Launcher("memory")
    launcher.add_pkg(components=[component])
    with launcher:
        seen: list[str] = []
        sub = launcher.transport.create_subscription(MOTION, seen.append)
        bridge = McpBridge(launcher.transport, components=["arm"], audit_log=tmp_path / "audit.jsonl")
        server = bridge.serve_http(port=0)
        try:
            yield component, server, seen
        finally:
            server.stop()
            sub.close()
