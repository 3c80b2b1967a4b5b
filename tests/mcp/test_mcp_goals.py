"""An action server's goals as an MCP tool: feedback arrives as progress, a cancelled call stops the goal."""

from __future__ import annotations

import threading
from typing import Any

import anyio
import pytest

pytest.importorskip("mcp", reason="the mcp extra is not installed")

from mcp import Client

from agents_core import Launcher
from agents_core.components import Component
from agents_core.mcp import McpBridge
from agents_core.transport.goals import GoalHandle


class Mover(Component):
    """Counts steps until max_steps or a cancel, giving feedback each step."""

    _action_type = "VisionLanguageAction"

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(trigger=None, run_type="ActionServer", **kwargs)
        self.cancelled = threading.Event()
        self.finished_steps: list[int] = []

    def main_action_callback(self, goal_handle: GoalHandle) -> dict[str, Any]:
        step = 0
        while step < goal_handle.goal["max_steps"] and not goal_handle.wait_for_cancel(0.02):
            step += 1
            goal_handle.publish_feedback({"step": step, "action": [0.1 * step], "status": "moving"})
        if goal_handle.cancel_requested:
            self.cancelled.set()
        self.finished_steps.append(step)
        return {"success": not goal_handle.cancel_requested, "steps": step}


@pytest.fixture
def served(tmp_path):
    mover = Mover(component_name="mover")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[mover])
    with launcher:
        bridge = McpBridge(launcher.transport, components=["mover"], audit_log=tmp_path / "audit.jsonl")
        server = bridge.serve_http(port=0)
        try:
            yield mover, server
        finally:
            server.stop()


def test_a_goal_reports_progress_and_its_result(served):
    mover, server = served
    progress: list[tuple[float, str | None]] = []

    async def on_progress(value: float, total: float | None, message: str | None) -> None:
        progress.append((value, message))

    async def go():
        async with Client(server.url) as client:
            tools = {t.name: t for t in (await client.list_tools()).tools}
            result = await client.call_tool("mover__goal", {"task": "reach", "max_steps": 5},
                                            progress_callback=on_progress)
            return tools, result

    tools, result = anyio.run(go)
    assert set(tools["mover__goal"].input_schema["properties"]) == {"task", "max_steps"}
    assert not result.is_error and '"steps": 5' in result.content[0].text
    assert len(progress) >= 1 and '"step"' in (progress[-1][1] or "")
    assert mover.finished_steps == [5]


def test_cancelling_the_call_cancels_the_goal(served):
    mover, server = served

    async def go():
        async with Client(server.url) as client:
            with anyio.move_on_after(1.0):  # the caller gives up: the MCP request is cancelled
                await client.call_tool("mover__goal", {"task": "reach", "max_steps": 100000})
            await anyio.sleep(0.5)

    anyio.run(go)
    assert mover.cancelled.wait(10), "the goal went on after its MCP call was cancelled"
    assert mover.finished_steps and mover.finished_steps[0] < 100000
