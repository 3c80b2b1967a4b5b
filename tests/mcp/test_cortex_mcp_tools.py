"""The Cortex planner uses a third-party MCP server's tools (npm's reference "everything" server, over stdio)
under the same guardrails as the LLM's: a result reaches the planner, a limit refuses an out-of-range
call before it is sent, and a tool that needs approval runs once approved.

The planner is the tests' scripted Ollama-protocol server (real HTTP); every step is confirmed.
"""

from __future__ import annotations

import json
import threading

import pytest

pytest.importorskip("mcp", reason="the mcp extra is not installed")

from agents_core import Launcher
from agents_core.clients import OllamaClient
from agents_core.components import Cortex
from agents_core.config import CortexConfig
from agents_core.guardrails import approvals, configure_audit_log
from agents_core.models import OllamaModel
from agents_core.testing.helpers import wait_for
from agents_core.transport.goals import GoalStatus

from ..servers.scripted_ollama_server import ScriptedOllamaServer, calls, text
from .npm_tools import EVERYTHING, npm_binary


def _task(launcher: Launcher, task: str) -> tuple[GoalStatus, dict]:
    goal = launcher.transport.send_goal("cortex", "VisionLanguageAction", {"task": task}, timeout=5.0)
    assert goal.accepted
    return goal.result(60.0)


def _said_to_planner(body: dict) -> str:
    return json.dumps([m.get("content") for m in body["messages"]])


def test_the_cortex_plans_with_mcp_tools_under_their_guardrails(tmp_path):
    server_binary = npm_binary(EVERYTHING)
    configure_audit_log(tmp_path / "audit.jsonl")
    plan = [calls(("everything__get-sum", {"a": 2, "b": 3})), text("The sum is 5."),
            calls(("everything__get-sum", {"a": 50, "b": 1})), text("I may not add 50."),
            calls(("everything__echo", {"message": "hello robot"})), text("Echoed.")]
    try:
        with ScriptedOllamaServer(plan=plan, models=["llama3.2:3b"]) as ollama:
            config = CortexConfig(
                max_planning_steps=3, max_execution_steps=2, monitoring_interval=0.05,
                mcp_servers=[{"target": [str(server_binary)], "name": "everything", "allow": ["get-sum", "echo"],
                              "limits": {"get-sum": {"a": (0, 10)}}, "approval": ["echo"],
                              "approval_timeout": 20.0}])
            cortex = Cortex(config=config, component_name="cortex",
                            model_client=OllamaClient(OllamaModel(name="m", checkpoint="llama3.2:3b"),
                                                      port=ollama.port))
            launcher = Launcher("memory")
            launcher.add_pkg(components=[cortex])
            with launcher:
                offered = sorted(n for n in cortex.tool_names if "__" in n)
                summed = _task(launcher, "what is 2 + 3?")
                refused = _task(launcher, "what is 50 + 1?")
                decided: list[bool] = []

                def approve() -> None:
                    assert wait_for(lambda: bool(approvals().pending()), 20.0)
                    call = approvals().pending()[0]
                    decided.append(call["action"] == "everything__echo" and call["caller"] == "cortex"
                                   and approvals().decide(call["id"], True, by="test operator"))

                helper = threading.Thread(target=approve)
                helper.start()
                echoed = _task(launcher, "say hello robot")
                helper.join(30)
        assert offered == ["everything__echo", "everything__get-sum"]  # the allow-list: nothing else
        tools = {t["function"]["name"]: t["function"] for t in ollama.planning_requests[0]["tools"]}
        assert tools["everything__get-sum"]["parameters"]["properties"]["a"]["maximum"] == 10
        assert summed[0] == GoalStatus.SUCCEEDED, summed
        assert "The sum of 2 and 3 is 5" in _said_to_planner(ollama.planning_requests[1])  # the server's answer
        assert refused[0] == GoalStatus.SUCCEEDED, refused  # the planner was told, then answered in text
        told = _said_to_planner(ollama.planning_requests[3])
        assert "must be <= 10" in told and "51" not in told  # refused before it was sent: never summed
        assert decided == [True] and echoed[0] == GoalStatus.SUCCEEDED, echoed
        assert "hello robot" in _said_to_planner(ollama.planning_requests[5])
        records = [json.loads(line) for line in (tmp_path / "audit.jsonl").read_text().splitlines()]
        echo = [r for r in records if r.get("action") == "everything__echo"]
        assert [(r["caller"], r["decision"], r.get("approved_by")) for r in echo] == [
            ("cortex", "allowed", "test operator")]
        assert cortex._mcp_boxes == []  # disconnected at shutdown: the server process ended
    finally:
        configure_audit_log(None)
