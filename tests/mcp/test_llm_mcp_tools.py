"""Our LLM calls the tools of a third-party MCP server (npm's reference "everything" server, over stdio),
under the same guardrails as our own actions: a limited tool refuses the model's out-of-range call.

The model is the tests' scripted Ollama-protocol server (real HTTP): it asks for the tool, then
answers with what the tool returned.
"""

from __future__ import annotations

import json

import pytest

pytest.importorskip("mcp", reason="the mcp extra is not installed")

from agents_core import Launcher, Topic
from agents_core.clients import OllamaClient
from agents_core.components import LLM
from agents_core.config import LLMConfig
from agents_core.errors import ConfigError
from agents_core.models import OllamaModel
from agents_core.testing.helpers import wait_for

from ..servers.scripted_ollama_server import ScriptedOllamaServer, calls, text
from .npm_tools import EVERYTHING, npm_binary


def _tool_messages(body):
    return [m for m in body["messages"] if m.get("role") == "tool"]


def test_the_llm_calls_a_third_party_mcp_tool_and_a_limit_refuses_its_out_of_range_call():
    server_binary = npm_binary(EVERYTHING)
    plan = [calls(("everything__get-sum", {"a": 2, "b": 3})), lambda body: text("the sum is in the tool result"),
            calls(("everything__get-sum", {"a": 50, "b": 1})), lambda body: text("refused")]
    question, answers = Topic("question", "String"), Topic("answer", "String")
    with ScriptedOllamaServer(plan=plan, models=["llama3.2:3b"]) as ollama:
        config = LLMConfig(mcp_servers=[{"target": [str(server_binary)], "name": "everything",
                                         "allow": ["get-sum", "echo"],
                                         "limits": {"get-sum": {"a": (0, 10)}}}])
        llm = LLM(inputs=[question], outputs=[answers], trigger=question, config=config, component_name="brain",
                  model_client=OllamaClient(OllamaModel(name="m", checkpoint="llama3.2:3b"), port=ollama.port))
        launcher = Launcher("memory")
        launcher.add_pkg(components=[llm])
        with launcher:
            got: list[str] = []
            sub = launcher.transport.create_subscription(answers, got.append)
            pub = launcher.transport.create_publisher(question)
            offered = sorted(llm._tools)
            pub.publish("what is 2 + 3?")
            assert wait_for(lambda: len(got) >= 1, 30)
            pub.publish("what is 50 + 1?")
            assert wait_for(lambda: len(got) >= 2, 30)
            sub.close()
    assert offered == ["everything__echo", "everything__get-sum"]  # the allow-list: nothing else offered
    first_call = ollama.planning_requests[0]
    tools = {t["function"]["name"]: t["function"] for t in first_call["tools"]}
    assert tools["everything__get-sum"]["parameters"]["properties"]["a"]["maximum"] == 10
    sum_result = _tool_messages(ollama.planning_requests[1])[-1]["content"]
    assert "5" in sum_result  # the everything server's own answer
    refused = _tool_messages(ollama.planning_requests[3])[-1]["content"]
    assert "outside [0, 10]" in refused and "did not run" in refused
    assert json.dumps(got)


def test_a_bad_mcp_server_entry_is_refused_at_configuration():
    with pytest.raises(ConfigError, match="http"):
        LLMConfig(mcp_servers=["not a url"])
    with pytest.raises(ConfigError, match="command line"):
        LLMConfig(mcp_servers=[42])
    with pytest.raises(ConfigError, match="limits"):
        LLMConfig(mcp_servers=[{"target": "http://127.0.0.1:1/mcp", "limits": {"t": {"a": (5, 1)}}}])
