"""``python -m tests.mcp.serve_parts PORT SECONDS``: the Arm recipe on memory, served over MCP HTTP on PORT."""

from __future__ import annotations

import sys
import time

from agents_core import Launcher
from agents_core.mcp import McpBridge

from .mcp_parts import arm


def main() -> int:
    port, seconds = int(sys.argv[1]), float(sys.argv[2])
    launcher = Launcher("memory")
    launcher.add_pkg(components=[arm()])
    with launcher:
        server = McpBridge(launcher.transport, components=["arm"], audit_log=sys.argv[3]).serve_http(port=port)
        print("READY", server.url, flush=True)
        time.sleep(seconds)  # bounded: the test stops it sooner
        server.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
