"""Approval asked of the MCP client through elicitation (the official SDK's client answering it).

Both ways the protocol allows: the 2026-07-28 ``input_required`` round trip (the SDK client's
default) and an ``elicitation/create`` request on a session opened by the handshake (``legacy``).
"""

from __future__ import annotations

import json
import threading
import time

import anyio
import pytest

pytest.importorskip("mcp", reason="the mcp extra is not installed")

import mcp_types as types
from mcp import Client

from agents_core.guardrails import approvals
from agents_core.testing.helpers import wait_for

MODES = ["auto", "legacy"]


def _answering(action, approve=None, delay=0.0, asked=None):
    async def callback(context, params):
        if asked is not None:
            asked.append(params.message)
        if delay:
            await anyio.sleep(delay)
        content = {"approve": approve} if approve is not None else None
        return types.ElicitResult(action=action, content=content)

    return callback


def _call(server, callback, mode, target):
    async def go():
        async with Client(server.url, elicitation_callback=callback, mode=mode,
                          client_info=types.Implementation(name="test-desk", version="1")) as client:
            return await client.call_tool("arm__launch", {"target": target})

    return anyio.run(go)


def _records(tmp_path, key, value):
    lines = (tmp_path / "audit.jsonl").read_text().splitlines()
    return [r for r in map(json.loads, lines) if r.get(key) == value]


@pytest.mark.parametrize("mode", MODES)
def test_a_yes_runs_the_call_once(served, tmp_path, mode):
    component, server, seen = served
    asked: list[str] = []
    result = _call(server, _answering("accept", True, asked=asked), mode, "the moon")
    assert not result.is_error, result
    assert "launched at the moon" in result.content[0].text
    assert len(asked) == 1 and "arm.launch" in asked[0] and "the moon" in asked[0]
    assert wait_for(lambda: "launched at the moon" in seen, 5.0)
    time.sleep(0.3)
    assert component.launches == ["the moon"]
    assert approvals().pending() == []
    bridge = _records(tmp_path, "tool", "arm__launch")
    assert [(r["decision"], r["approval_decision"], r["decided_by"]) for r in bridge] == [
        ("allowed", "approved", "mcp elicitation (test-desk)")]
    core = [r for r in _records(tmp_path, "action", "launch") if r["decision"] == "allowed"]
    assert [r.get("approved_by") for r in core] == ["mcp elicitation (test-desk)"]


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("answer", [("decline", None), ("cancel", None), ("accept", False)])
def test_a_no_refuses_the_call_and_it_never_runs(served, tmp_path, mode, answer):
    component, server, seen = served
    start = time.monotonic()
    result = _call(server, _answering(*answer), mode, "mars")
    assert result.is_error and "denied by mcp elicitation (test-desk)" in result.content[0].text
    assert time.monotonic() - start < 4.0  # refused at the answer, not at the 5 s timeout
    time.sleep(0.5)
    assert component.launches == [] and "launched at mars" not in seen
    [record] = _records(tmp_path, "tool", "arm__launch")
    assert record["decision"] == "refused" and record["approval_decision"].startswith("denied")
    assert record["decided_by"] == "mcp elicitation (test-desk)"


@pytest.mark.parametrize("mode", MODES)
def test_no_answer_in_time_refuses_the_call_and_a_late_yes_does_not_run_it(served, tmp_path, mode):
    component, server, seen = served
    start = time.monotonic()
    result = _call(server, _answering("accept", True, delay=6.5), mode, "venus")  # the action waits 5 s
    assert result.is_error and "did not run" in result.content[0].text
    assert 4.5 < time.monotonic() - start < 20
    time.sleep(0.5)
    assert component.launches == [] and "launched at venus" not in seen
    [record] = _records(tmp_path, "tool", "arm__launch")
    assert record["decision"] == "refused"
    assert record["approval_decision"] in ("no answer in time", "answered too late (yes): refused")


def test_a_forged_request_state_runs_nothing(served):
    component, server, _ = served

    async def go():
        async with Client(server.url, elicitation_callback=_answering("accept", True)) as client:
            return await client.session.call_tool(
                "arm__launch", {"target": "x"}, allow_input_required=True, request_state="forged-handle",
                input_responses={"approval": types.ElicitResult(action="accept", content={"approve": True})})

    result = anyio.run(go)
    assert result.is_error and "no call waits for this answer" in result.content[0].text
    assert component.launches == []


def test_a_client_without_elicitation_keeps_the_approvals_service_path(served):
    component, server, _ = served

    async def go():
        async with Client(server.url) as client:
            return await client.call_tool("arm__launch", {"target": "home"})

    def approve():
        assert wait_for(lambda: bool(approvals().pending()), 5.0)
        approvals().decide(approvals().pending()[0]["id"], True, by="operator")

    helper = threading.Thread(target=approve)
    helper.start()
    result = anyio.run(go)
    helper.join(10)
    assert not result.is_error and component.launches == ["home"]
