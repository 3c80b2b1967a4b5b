"""An action called through MCP against the same call through ``execute_method`` (memory transport, one run).

One child process launches an Arm with a ``@component_action`` (it returns at once) on the memory
transport and serves it over MCP's Streamable HTTP on loopback. Per repetition, interleaved: the
raw side is ``transport.request("arm/execute_method", ...)`` (what the CLI, the UI and other
components use); the framework side is the official SDK client's ``call_tool("arm__count")`` on a
session kept open (JSON-RPC over HTTP, the SDK's validation, the bridge's state check and audit
record, then the same ``execute_method``). Reported as ms per call, p50 / p99.
``python -m benchmarks.mcp --reps N`` is the child; :func:`run_suite` runs it.
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .common import Children, child_main, emit, run_memory_child


def run_child(reps: int, warmup: int) -> None:
    import anyio  # noqa: PLC0415
    import numpy as np  # noqa: PLC0415
    from mcp import Client  # noqa: PLC0415

    from agents_core.actions import component_action  # noqa: PLC0415
    from agents_core.components import Component  # noqa: PLC0415
    from agents_core.launch.launcher import Launcher  # noqa: PLC0415
    from agents_core.mcp import McpBridge  # noqa: PLC0415

    class Arm(Component):
        def __init__(self) -> None:
            super().__init__(trigger=0.1, component_name="arm")
            self.calls = 0

        @component_action
        def count(self) -> int:
            """How many calls so far."""
            self.calls += 1
            return self.calls

        def _execution_step(self, **kwargs: Any) -> None:
            pass

    launcher = Launcher("memory")
    launcher.add_pkg(components=[Arm()])
    raw: list[float] = []
    framework: list[float] = []
    with launcher, tempfile.TemporaryDirectory() as folder:
        server = McpBridge(launcher.transport, components=["arm"],
                           audit_log=Path(folder) / "audit.jsonl").serve_http(port=0)
        transport = launcher.transport

        async def measure() -> None:
            async with Client(server.url) as client:
                for rep in range(warmup + reps):
                    start = time.perf_counter()
                    transport.request("arm/execute_method", {"method": "count"}, timeout=10.0)
                    middle = time.perf_counter()
                    result = await client.call_tool("arm__count", {})
                    end = time.perf_counter()
                    if result.is_error:
                        raise RuntimeError(f"MCP call failed: {result.content}")
                    if rep >= warmup:
                        raw.append((middle - start) * 1000.0)
                        framework.append((end - middle) * 1000.0)

        try:
            anyio.run(measure)
        finally:
            server.stop()
    for mode, values in (("raw", raw), ("framework", framework)):
        emit({"suite": "mcp", "transport": "memory", "payload": "action_call", "mode": mode,
              "latency_ms": {"p50": statistics.median(values), "p99": float(np.percentile(values, 99))},
              "reps": reps})


def run_suite(settings: dict[str, Any], children: Children,
              progress: Callable[[str], None]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """The mcp child; (records, skipped)."""
    try:
        import mcp  # noqa: F401, PLC0415
    except ImportError:
        return [], [{"suite": "mcp", "transport": "memory", "mode": "framework",
                     "reason": "the mcp extra is not installed (pip install 'agents-core[mcp]')"}]
    return run_memory_child("mcp", settings, children, progress, reps=200, warmup=20, what="per action call")


def main(argv: list[str] | None = None) -> int:
    return child_main(argv, __doc__, run_child, name="mcp", reps=200, warmup=20)


if __name__ == "__main__":
    sys.exit(main())
