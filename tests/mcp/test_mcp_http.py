"""A recipe served over MCP's Streamable HTTP, driven by the official SDK's client (memory transport)."""

from __future__ import annotations

import json
import threading
import time

import anyio
import httpx
import pytest

pytest.importorskip("mcp", reason="the mcp extra is not installed")

from mcp import Client

from agents_core import Launcher
from agents_core.errors import AgentsError, ConfigError
from agents_core.guardrails import approvals
from agents_core.mcp.server import McpHttpServer
from agents_core.testing.helpers import wait_for

from .mcp_parts import arm


def _run(coro_fn, *args):
    return anyio.run(coro_fn, *args)


def test_tools_listed_with_schemas_and_a_call_changes_the_topic(served):
    component, server, seen = served

    async def go():
        async with Client(server.url) as client:
            tools = {t.name: t for t in (await client.list_tools()).tools}
            result = await client.call_tool("arm__move", {"speed": 0.25})
            return tools, result

    tools, result = _run(go)
    assert {"arm__move", "arm__launch", "arm__count"} <= set(tools)
    move = tools["arm__move"].input_schema
    assert move["properties"]["speed"] == {"type": "number", "description": "metres a second",
                                           "minimum": 0.0, "maximum": 0.5}
    assert move["required"] == ["speed"]
    assert tools["arm__move"].description.startswith("Move the arm forward")
    assert not result.is_error and "moved 1.0 m at 0.25 m/s" in result.content[0].text
    assert wait_for(lambda: "moved 1.0 m at 0.25 m/s" in seen, 5.0)
    assert component.moves == [0.25]


@pytest.mark.parametrize("arguments", [{"speed": 0.9}, {"speed": -1}, {"speed": "fast"}, {"speed": 0.1, "power": 9},
                                       {}])
def test_out_of_range_or_bad_arguments_are_refused_and_never_run(served, arguments):
    component, server, _ = served

    async def go():
        async with Client(server.url) as client:
            return await client.call_tool("arm__move", arguments)

    result = _run(go)
    assert result.is_error, result
    assert component.moves == []


def test_the_core_refuses_out_of_range_whoever_calls(served):
    """The same limit through execute_method (what the CLI, the UI and other components use)."""
    component, server, _ = served
    with pytest.raises(AgentsError, match=r"'speed' = 0.7 is outside \[0, 0.5\]"):
        server.bridge.catalog.transport.request("arm/execute_method",
                                                {"method": "move", "kwargs": {"speed": 0.7}}, timeout=5.0)
    with pytest.raises(AgentsError, match="outside"):
        component.move(float("nan"))
    assert component.moves == []


def test_an_approval_granted_runs_once_and_one_timed_out_never_runs(served):
    component, server, seen = served
    decided: list[bool] = []

    def approve_when_asked():
        assert wait_for(lambda: bool(approvals().pending()), 5.0)
        call = approvals().pending()[0]
        assert call["component"] == "arm" and call["action"] == "launch" and call["caller"] == "mcp"
        decided.append(approvals().decide(call["id"], True, by="test operator"))

    helper = threading.Thread(target=approve_when_asked)
    helper.start()

    async def go(target):
        async with Client(server.url) as client:
            return await client.call_tool("arm__launch", {"target": target})

    granted = _run(go, "the moon")
    helper.join(10)
    assert decided == [True]
    assert not granted.is_error and "launched at the moon" in granted.content[0].text
    start = time.monotonic()
    refused = _run(go, "mars")  # nobody answers: refused after the action's 5 s
    assert refused.is_error and "not approved within 5 s" in refused.content[0].text
    assert 4.5 < time.monotonic() - start < 15
    time.sleep(0.5)
    assert component.launches == ["the moon"] and "launched at mars" not in seen
    assert approvals().pending() == []


def test_resources_health_recipe_and_topic(served):
    _, server, _ = served

    async def go():
        async with Client(server.url) as client:
            uris = [str(r.uri) for r in (await client.list_resources()).resources]
            await client.call_tool("arm__move", {"speed": 0.1, "distance": 2.0})
            await client.read_resource("agents://topic/motion")  # subscribes on first read
            await client.call_tool("arm__move", {"speed": 0.2})
            time.sleep(0.3)
            motion = await client.read_resource("agents://topic/motion")
            health = await client.read_resource("agents://health")
            return uris, motion, health

    uris, motion, health = _run(go)
    assert {"agents://recipe", "agents://health", "agents://topic/motion"} <= set(uris)
    assert json.loads(motion.contents[0].text)["value"] == "moved 1.0 m at 0.2 m/s"
    assert json.loads(health.contents[0].text)["arm"]["state"] == "active"


def test_hostile_http_requests_are_bounded(served):
    _, server, _ = served
    headers = {"content-type": "application/json", "accept": "application/json, text/event-stream"}
    with httpx.Client(timeout=10) as http:
        big = http.post(server.url, content=b"[" * (2 << 20), headers=headers)
        assert big.status_code in (400, 413)
        evil = http.post(server.url, content=b"{}", headers={**headers, "origin": "http://evil.example"})
        assert evil.status_code in (400, 403)
        unknown = http.post(server.url, json={"jsonrpc": "2.0", "id": 1, "method": "no/such", "params": {}},
                            headers=headers)
        assert unknown.status_code in (200, 400, 404)
        if unknown.status_code == 200 and unknown.text:
            assert "error" in unknown.text
    # still serving
    async def go():
        async with Client(server.url) as client:
            return await client.call_tool("arm__count", {})

    assert "0" in _run(go).content[0].text


def test_off_loopback_needs_a_token():
    class _NoBridge:
        pass

    with pytest.raises(ConfigError, match="needs a token"):
        McpHttpServer(_NoBridge(), "0.0.0.0", 0, None)  # type: ignore[arg-type]
    assert "token=set" in repr(McpHttpServer(_NoBridge(), "0.0.0.0", 0, "x" * 32))  # type: ignore[arg-type]
    assert "x" * 32 not in repr(McpHttpServer(_NoBridge(), "0.0.0.0", 0, "x" * 32))  # type: ignore[arg-type]


def test_a_topic_resource_subscription_sees_updates(served):
    _, server, _ = served
    events: list[str] = []

    async def go():
        async with Client(server.url) as client:
            async with client.listen(resource_subscriptions=["agents://topic/motion"]) as subscription:
                await client.call_tool("arm__move", {"speed": 0.3})
                with anyio.move_on_after(10):
                    async for event in subscription:
                        events.append(str(event.uri))
                        break
            latest = await client.read_resource("agents://topic/motion")
            return json.loads(latest.contents[0].text)

    latest = _run(go)
    assert events == ["agents://topic/motion"]
    assert latest["value"] == "moved 1.0 m at 0.3 m/s"


def test_launcher_enable_mcp_serves_the_recipe(tmp_path):
    component = arm()
    launcher = Launcher("memory")
    launcher.add_pkg(components=[component])
    launcher.enable_mcp(port=0, audit_log=tmp_path / "audit.jsonl", allow=["arm__move", "arm__count"])
    with launcher:
        url = launcher.mcp.url

        async def go():
            async with Client(url) as client:
                names = [t.name for t in (await client.list_tools()).tools]
                return names, await client.call_tool("arm__move", {"speed": 0.2})

        names, moved = _run(go)
    assert names == ["arm__count", "arm__move"]  # the allow-list: arm__launch is not offered
    assert not moved.is_error and component.moves == [0.2]
    assert launcher.mcp is None  # stopped with the recipe
    records = [json.loads(line) for line in (tmp_path / "audit.jsonl").read_text().splitlines()]
    assert any(r.get("tool") == "arm__move" and r["decision"] == "allowed" for r in records)


def test_enable_mcp_off_loopback_without_a_token_is_refused(monkeypatch):
    monkeypatch.delenv("AGENTS_MCP_TOKEN", raising=False)
    launcher = Launcher("memory")
    with pytest.raises(ConfigError, match="needs a token"):
        launcher.enable_mcp(host="0.0.0.0")
