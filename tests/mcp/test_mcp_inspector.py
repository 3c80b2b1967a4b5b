"""Interop: the MCP Inspector's CLI (npm ``@modelcontextprotocol/inspector``, written by the protocol's
maintainers) lists and calls the tools of a running recipe over Streamable HTTP.

The package is installed once into a cache folder (:mod:`tests.mcp.npm_tools`).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("mcp", reason="the mcp extra is not installed")

from agents_core.testing.helpers import free_tcp_port

from .npm_tools import INSPECTOR, npm_binary
from .processes import stop_group

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def inspector() -> Path:
    return npm_binary(INSPECTOR)


@pytest.fixture
def mcp_url(tmp_path):
    port = free_tcp_port()
    proc = subprocess.Popen([sys.executable, "-m", "tests.mcp.serve_parts", str(port), "120",
                             str(tmp_path / "audit.jsonl")], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert "READY" in line, line + proc.stdout.read()
        yield f"http://127.0.0.1:{port}/mcp"
    finally:
        stop_group(proc)


def _inspect(binary: Path, url: str, *args: str) -> dict:
    done = subprocess.run([str(binary), "--cli", url, *args], capture_output=True, text=True, timeout=120,
                          check=False)
    out = done.stdout[done.stdout.index("{"):] if "{" in done.stdout else done.stdout
    decoder = json.JSONDecoder()
    return decoder.raw_decode(out)[0]


def test_the_inspector_lists_and_calls_the_recipes_tools(inspector, mcp_url):
    started = time.monotonic()
    listed = _inspect(inspector, mcp_url, "--method", "tools/list")
    names = {t["name"] for t in listed["tools"]}
    assert {"arm__move", "arm__launch", "arm__count"} <= names
    move = next(t for t in listed["tools"] if t["name"] == "arm__move")
    assert move["inputSchema"]["properties"]["speed"]["maximum"] == 0.5
    moved = _inspect(inspector, mcp_url, "--method", "tools/call", "--tool-name", "arm__move", "--tool-arg",
                     "speed=0.3")
    assert moved["isError"] is False and "moved 1.0 m at 0.3 m/s" in moved["content"][0]["text"]
    refused = _inspect(inspector, mcp_url, "--method", "tools/call", "--tool-name", "arm__move", "--tool-arg",
                       "speed=0.9")
    assert refused["isError"] is True and "outside" in refused["content"][0]["text"]
    count = _inspect(inspector, mcp_url, "--method", "tools/call", "--tool-name", "arm__count")
    assert count["content"][0]["text"].strip() == "1"
    assert time.monotonic() - started < 110  # the server lives 120 s
