"""Hostile MCP clients: deep JSON, 100 parallel sessions, a client that never reads, a call during deactivate."""

from __future__ import annotations

import socket
import threading

import anyio
import httpx
import pytest

pytest.importorskip("mcp", reason="the mcp extra is not installed")

from mcp import Client

HEADERS = {"content-type": "application/json", "accept": "application/json, text/event-stream"}
INIT = {"jsonrpc": "2.0", "id": 1, "method": "initialize",
        "params": {"protocolVersion": "2025-06-18", "capabilities": {},
                   "clientInfo": {"name": "hostile", "version": "0"}}}


def _still_serves(server) -> str:
    async def go():
        async with Client(server.url) as client:
            return (await client.call_tool("arm__count", {})).content[0].text

    return anyio.run(go)


def test_deep_and_malformed_json_rpc_bodies_are_clear_errors(served):
    _, server, _ = served
    with httpx.Client(timeout=10) as http:
        deep = http.post(server.url, content=b'{"a":' * 100_000 + b"1" + b"}" * 100_000, headers=HEADERS)
        assert deep.status_code in (400, 413)
        garbage = http.post(server.url, content=b"\xff\xfe not json", headers=HEADERS)
        assert garbage.status_code == 400
        wrong = http.post(server.url, json={"jsonrpc": "1.0", "id": [], "method": 5}, headers=HEADERS)
        assert wrong.status_code in (400, 404, 422)
    assert _still_serves(server).strip() == "0"


def test_a_hundred_parallel_sessions_are_bounded(served):
    _, server, _ = served
    statuses: list[int] = []
    lock = threading.Lock()

    def open_session():
        try:
            with httpx.Client(timeout=20) as http:
                reply = http.post(server.url, json=INIT, headers=HEADERS)
                with lock:
                    statuses.append(reply.status_code)
        except httpx.HTTPError:
            with lock:
                statuses.append(-1)

    threads = [threading.Thread(target=open_session) for _ in range(100)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert len(statuses) == 100
    # Each answered: a session, or a refusal once the cap is reached; none hung.
    assert all(s in (200, 400, 429, 503) for s in statuses), sorted(set(statuses))
    assert statuses.count(200) <= 64 + 1
    assert _still_serves(server).strip() == "0"


def test_a_client_that_never_reads_does_not_stop_the_others(served):
    _, server, _ = served
    host, port = "127.0.0.1", server.port
    stalled = []
    for _ in range(20):  # connections that send half a request and never read
        s = socket.create_connection((host, port), timeout=5)
        s.sendall(b"POST /mcp HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                  b"Content-Length: 100000\r\n\r\n{\"jsonrpc\":")
        stalled.append(s)
    try:
        assert _still_serves(server).strip() == "0"
    finally:
        for s in stalled:
            s.close()


def test_a_tool_call_while_the_component_deactivates_is_a_clear_error(served):
    component, server, _ = served

    async def go():
        async with Client(server.url) as client:
            component.deactivate()
            try:
                return await client.call_tool("arm__move", {"speed": 0.1})
            finally:
                component.activate()

    result = anyio.run(go)
    assert result.is_error and result.content[0].text
    assert component.moves == []
    assert _still_serves(server).strip() == "0"
