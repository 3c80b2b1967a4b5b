"""``agentsctl mcp`` over stdio (the form desktop AI clients start), for a recipe in another process on Zenoh.

The official SDK's stdio client starts ``agentsctl mcp``; the recipe runs in a process of its own;
``agentsctl approve`` (a third process) grants a held call.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import anyio
import pytest

pytest.importorskip("mcp", reason="the mcp extra is not installed")
pytest.importorskip("zenoh", reason="the zenoh extra is not installed")

from mcp import Client, StdioServerParameters

from agents_core.testing.helpers import free_tcp_port

from .processes import stop_group

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def zenoh_recipe(tmp_path):
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    proc = subprocess.Popen([sys.executable, "-m", "tests.mcp.mcp_parts", "--listen", endpoint], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        assert proc.stdout is not None
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if "READY" in line or not line:
                break
        assert proc.poll() is None, "the recipe process ended before it was ready"
        yield endpoint
    finally:
        stop_group(proc)


def _agentsctl(*args: str) -> list[str]:
    return [sys.executable, "-m", "agents_core.cli", *args]


def test_stdio_lists_calls_refuses_and_an_approval_from_agentsctl_runs_it(zenoh_recipe, tmp_path):
    audit = tmp_path / "audit.jsonl"
    command = _agentsctl("mcp", "--transport", "zenoh", "--connect", zenoh_recipe, "--audit-log", str(audit))
    params = StdioServerParameters(command=command[0], args=command[1:], cwd=str(ROOT), env=dict(os.environ))
    approved: list[subprocess.CompletedProcess[str]] = []

    def approve_when_waiting():
        for _ in range(80):  # bounded: about 40 s plus the processes' start
            time.sleep(0.5)
            done = subprocess.run(_agentsctl("approve", "--transport", "zenoh", "--connect", zenoh_recipe),
                                  capture_output=True, text=True, timeout=60, cwd=ROOT, check=False)
            if done.returncode == 0:
                approved.append(done)
                return

    async def go():
        async with Client(params, read_timeout_seconds=60) as client:
            names = [t.name for t in (await client.list_tools()).tools]
            moved = await client.call_tool("arm__move", {"speed": 0.4, "distance": 0.5})
            refused = await client.call_tool("arm__move", {"speed": 3.0})
            helper = threading.Thread(target=approve_when_waiting)
            helper.start()
            launched = await client.call_tool("arm__launch", {"target": "the bin"})
            helper.join(90)
            count = await client.call_tool("arm__count", {})
            return names, moved, refused, launched, count

    names, moved, refused, launched, count = anyio.run(go)
    assert {"arm__move", "arm__launch", "arm__count"} <= set(names)
    assert not moved.is_error and "moved 0.5 m at 0.4 m/s" in moved.content[0].text
    assert refused.is_error and "outside" in refused.content[0].text
    assert approved, "agentsctl approve never found the held call"
    assert "approved" in approved[0].stdout
    assert not launched.is_error and "launched at the bin" in launched.content[0].text
    assert count.content[0].text.strip() == "1"  # the refused move never ran
    records = [json.loads(line) for line in audit.read_text().splitlines()]
    assert [(r["tool"], r["decision"]) for r in records] == [
        ("arm__move", "allowed"), ("arm__move", "refused"), ("arm__launch", "allowed"), ("arm__count", "allowed")]
    assert all(r["caller"] == "mcp" and r["time"] > 0 for r in records)
    assert "outside" in records[1]["outcome"]


def test_stdio_elicitation_approves_a_call_held_in_another_process(zenoh_recipe, tmp_path):
    """The client's own user decides (elicitation): the call is held by the recipe's process, and
    ``agentsctl mcp`` settles it through that component's approvals service over Zenoh."""
    import mcp_types as types  # noqa: PLC0415

    audit = tmp_path / "audit.jsonl"
    command = _agentsctl("mcp", "--transport", "zenoh", "--connect", zenoh_recipe, "--audit-log", str(audit))
    params = StdioServerParameters(command=command[0], args=command[1:], cwd=str(ROOT), env=dict(os.environ))
    asked: list[str] = []

    async def answer(context, question):
        asked.append(question.message)
        return types.ElicitResult(action="accept", content={"approve": "bin" in question.message})

    async def go():
        async with Client(params, read_timeout_seconds=60, elicitation_callback=answer,
                          client_info=types.Implementation(name="desk", version="1")) as client:
            yes = await client.call_tool("arm__launch", {"target": "the bin"})
            no = await client.call_tool("arm__launch", {"target": "the moon"})
            return yes, no

    yes, no = anyio.run(go)
    assert len(asked) == 2
    assert not yes.is_error and "launched at the bin" in yes.content[0].text
    assert no.is_error and "denied by mcp elicitation (desk)" in no.content[0].text
    records = [json.loads(line) for line in audit.read_text().splitlines()]
    assert [(r["decision"], r["approval_decision"], r["decided_by"]) for r in records] == [
        ("allowed", "approved", "mcp elicitation (desk)"),
        ("refused", "denied (approve: false)", "mcp elicitation (desk)")]
