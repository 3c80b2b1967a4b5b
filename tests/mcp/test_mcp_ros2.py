"""``agentsctl mcp --transport ros2`` over stdio, for a recipe in another process on ROS 2 (real rclpy nodes)."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import time
from pathlib import Path

import anyio
import pytest

pytest.importorskip("mcp", reason="the mcp extra is not installed")

from mcp import Client, StdioServerParameters

from agents_core.testing.pairs import private_ros_environment, skip_unless_installed

pytestmark = pytest.mark.ros2
ROOT = Path(__file__).resolve().parents[2]


def test_stdio_over_ros2_lists_calls_and_refuses():
    skip_unless_installed("ros2", "agents_interfaces")
    private_ros_environment()
    recipe = subprocess.Popen([sys.executable, "-m", "tests.mcp.mcp_parts", "--transport", "ros2"], cwd=ROOT,
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                              env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        assert recipe.stdout is not None
        assert recipe.stdout.readline().strip() == "READY", "the recipe process did not start"
        command = [sys.executable, "-m", "agents_core.cli", "mcp", "--transport", "ros2"]
        params = StdioServerParameters(command=command[0], args=command[1:], cwd=str(ROOT), env=dict(os.environ))

        async def go():
            async with Client(params, read_timeout_seconds=60) as client:
                names: list[str] = []
                for _ in range(20):  # bounded: DDS discovery takes a moment
                    names = [t.name for t in (await client.list_tools()).tools]
                    if "arm__move" in names:
                        break
                    await anyio.sleep(0.5)
                moved = await client.call_tool("arm__move", {"speed": 0.2})
                refused = await client.call_tool("arm__move", {"speed": 0.6})
                count = await client.call_tool("arm__count", {})
                return names, moved, refused, count

        started = time.monotonic()
        names, moved, refused, count = anyio.run(go)
        assert "arm__move" in names, names
        assert not moved.is_error and "moved 1.0 m at 0.2 m/s" in moved.content[0].text
        assert refused.is_error and "outside" in refused.content[0].text
        assert count.content[0].text.strip() == "1"
        assert time.monotonic() - started < 120
    finally:
        recipe.terminate()
        with contextlib.suppress(subprocess.TimeoutExpired):
            recipe.wait(timeout=15)
        if recipe.poll() is None:
            recipe.kill()
            recipe.wait(timeout=5)
        recipe.stdout.close()  # type: ignore[union-attr]
