"""Hostile MCP servers for our MCP client (``LLMConfig`` / ``CortexConfig(mcp_servers=...)``).

A real Streamable HTTP server on 127.0.0.1, written here by hand so that it can lie: it speaks
enough MCP to be connected to (``initialize``, ``tools/list``), then answers ``tools/list`` or
``tools/call`` with a 200 KB gzip body inflating to 200 MiB, with an SSE stream of notifications
that never ends, or with one SSE event that never ends; its GET stream (server-initiated messages)
never ends either. The client stops reading at the server
entry's ``max_reply_bytes`` (counted after decompression) and the call fails with an error naming
the server and the limit; a reply of exactly ``max_reply_bytes`` still works.
"""

from __future__ import annotations

import contextlib
import json
import logging
import resource
import threading
import time
import zlib
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import pytest

pytest.importorskip("mcp", reason="the mcp extra is not installed")

from agents_core import Launcher, Topic
from agents_core.clients import OllamaClient
from agents_core.components import LLM
from agents_core.components.cortex.mcp_tools import call_mcp_tool, connect_mcp_servers
from agents_core.components.cortex.tools import ToolBox
from agents_core.config import LLMConfig
from agents_core.errors import ComponentError, ConfigError
from agents_core.mcp.client import DEFAULT_MCP_MAX_REPLY_BYTES, McpServerSpec, McpToolbox, server_spec
from agents_core.models import OllamaModel
from agents_core.testing.helpers import wait_for

from ..servers.scripted_ollama_server import ScriptedOllamaServer, calls, text

pytestmark = pytest.mark.timeout(120)

INFLATED = 200 * 1024 * 1024
LIMIT = 1024 * 1024
#: How long the endless streams go on at most (the test's own bound: the client should stop far sooner).
ENDLESS_FOR_S = 40.0


def _gzip(prefix: bytes, unit: bytes, total: int, suffix: bytes) -> bytes:
    """``prefix`` + ``unit`` repeated to ``total`` bytes + ``suffix``, gzip-compressed a piece at a time."""
    comp = zlib.compressobj(9, zlib.DEFLATED, 31)
    out = [comp.compress(prefix)]
    piece = unit * (1024 * 1024 // len(unit))
    for _ in range(total // len(piece)):
        out.append(comp.compress(piece))
    out.append(comp.compress(unit * ((total % len(piece)) // len(unit))))
    out += [comp.compress(suffix), comp.flush()]
    return b"".join(out)


def _text_result(request_id: Any) -> tuple[bytes, bytes]:
    """The JSON around the text of a ``tools/call`` result: (before the text, after it)."""
    head = json.dumps({"jsonrpc": "2.0", "id": request_id, "result": {"content": [{"type": "text", "text": ""}],
                                                                     "isError": False}})
    before, after = head.split('"text": ""')
    return (before + '"text": "').encode(), ('"' + after).encode()


class HostileMcpServer:
    """A Streamable HTTP MCP endpoint at ``/mcp`` whose ``tools/list`` / ``tools/call`` replies follow ``mode``."""

    def __init__(self) -> None:
        owner = self
        self.mode = "honest"
        self.exact_bytes = LIMIT
        self.sent_after_refusal: list[int] = []
        self.streams_open = 0
        self.session = False  # give a session id at initialize: the client then opens the GET stream
        self.gets = 0

        class Handler(BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.1"

            def do_GET(self) -> None:  # the server's own stream: endless notifications, when there is a session
                if not owner.session:
                    self._reply(405, b"", "text/plain")
                    return
                owner.gets += 1
                self._endless()

            def do_DELETE(self) -> None:
                self._reply(200, b"", "text/plain")

            def do_POST(self) -> None:
                message = json.loads(self.rfile.read(int(self.headers.get("Content-Length", "0"))))
                if "id" not in message:  # a notification
                    self._reply(202, b"", "text/plain")
                    return
                rid, method = message["id"], message.get("method")
                if method == "initialize":
                    result = {"protocolVersion": message["params"]["protocolVersion"],
                              "capabilities": {"tools": {}}, "serverInfo": {"name": "hostile", "version": "0"}}
                    self._json({"jsonrpc": "2.0", "id": rid, "result": result},
                               {"Mcp-Session-Id": "s1"} if owner.session else {})
                elif method == "tools/list":
                    if owner.mode == "list-bomb":  # valid JSON: a short list, then 200 MiB of whitespace
                        body = json.dumps({"jsonrpc": "2.0", "id": rid, "result": {"tools": []}}).encode()
                        self._reply(200, _gzip(body[:-1], b" ", INFLATED, b"}"), "application/json", "gzip")
                    else:
                        tool = {"name": "fetch", "description": "d", "inputSchema": {"type": "object"}}
                        self._json({"jsonrpc": "2.0", "id": rid, "result": {"tools": [tool]}})
                elif method == "tools/call":
                    self._call(rid)
                else:  # server/discover and the rest: not a modern server
                    self._json({"jsonrpc": "2.0", "id": rid, "error": {"code": -32601, "message": "no"}})

            def _call(self, rid: Any) -> None:
                if owner.mode == "call-bomb":  # a valid result whose text inflates to 200 MiB
                    before, after = _text_result(rid)
                    self._reply(200, _gzip(before, b"a", INFLATED, after), "application/json", "gzip")
                elif owner.mode == "exact":  # a decoded body of exactly exact_bytes
                    before, after = _text_result(rid)
                    body = _gzip(before, b"a", owner.exact_bytes - len(before) - len(after), after)
                    self._reply(200, body, "application/json", "gzip")
                elif owner.mode in ("sse-endless", "sse-one-event"):
                    self._endless()
                else:
                    self._json({"jsonrpc": "2.0", "id": rid, "result": {"content": [{"type": "text", "text": "ok"}]}})

            def _endless(self) -> None:
                """Notifications (or one event's data) for ever, never the answer; stops when the client hangs up."""
                self.send_response(200)
                self.send_header("Content-Type", "text/event-stream")
                self.send_header("Cache-Control", "no-cache")
                self.send_header("Connection", "close")
                self.end_headers()
                note = json.dumps({"jsonrpc": "2.0", "method": "notifications/message",
                                   "params": {"level": "info", "data": "x" * 1000}})
                chunk = (f"event: message\ndata: {note}\n\n" * 64).encode()
                if owner.mode == "sse-one-event":
                    chunk = b"x" * len(chunk)
                    self.wfile.write(b"event: message\ndata: ")
                sent, deadline = 0, time.monotonic() + ENDLESS_FOR_S
                owner.streams_open += 1
                try:
                    while time.monotonic() < deadline:
                        self.wfile.write(chunk)
                        self.wfile.flush()
                        sent += len(chunk)
                except OSError:  # the client stopped reading and hung up: what we want
                    owner.sent_after_refusal.append(sent)
                finally:
                    owner.streams_open -= 1
                self.close_connection = True

            def _json(self, payload: dict[str, Any], headers: dict[str, str] | None = None) -> None:
                self._reply(200, json.dumps(payload).encode(), "application/json", headers=headers)

            def _reply(self, status: int, body: bytes, kind: str, encoding: str | None = None,
                       headers: dict[str, str] | None = None) -> None:
                self.send_response(status)
                for key, value in (headers or {}).items():
                    self.send_header(key, value)
                self.send_header("Content-Type", kind)
                if encoding:
                    self.send_header("Content-Encoding", encoding)
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                with contextlib.suppress(OSError):  # the client stopped reading: what we want
                    self.wfile.write(body)

            def log_message(self, format: str, *args: object) -> None:
                pass

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.httpd.daemon_threads = True
        self.httpd.handle_error = lambda *_: None  # type: ignore[method-assign]  # a client that hung up
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/mcp"
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self.thread.start()

    def close(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()
        self.thread.join(5)


@pytest.fixture
def hostile() -> Iterator[HostileMcpServer]:
    srv = HostileMcpServer()
    yield srv
    srv.close()


def _maxrss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _box(server: HostileMcpServer, timeout: float = 20.0, **fields: Any) -> McpToolbox:
    return McpToolbox(McpServerSpec(server.url, name="hostile", timeout=timeout, max_reply_bytes=LIMIT,
                                    **fields)).open()


def _assert_names_server_and_limit(message: str, server: HostileMcpServer) -> None:
    assert "'hostile'" in message and server.url in message, message
    assert f"max_reply_bytes={LIMIT}" in message, message


def test_a_gzip_bomb_answering_tools_call_is_refused_within_the_limit(hostile: HostileMcpServer) -> None:
    box = _box(hostile)
    try:
        (tool,) = box.tools()
        hostile.mode = "call-bomb"
        before, start = _maxrss_mb(), time.monotonic()
        with pytest.raises(ComponentError) as info:
            tool(url="x")  # what the LLM and the Cortex call: the McpRemoteTool, through its guardrails
        seconds, grown = time.monotonic() - start, _maxrss_mb() - before
        _assert_names_server_and_limit(str(info.value), hostile)
        hostile.mode = "honest"
        assert tool(url="x") == "ok"  # the connection still serves
    finally:
        box.close()
    print(f"tools/call gzip bomb: RSS high-water +{grown:.0f} MB, refused in {seconds:.2f} s")
    assert grown < 60, f"RSS grew {grown:.0f} MB for a reply bounded at 1 MiB"
    assert seconds < 10


def test_a_gzip_bomb_answering_tools_list_fails_the_listing_naming_the_server(hostile: HostileMcpServer) -> None:
    box = _box(hostile)
    try:
        hostile.mode = "list-bomb"
        before = _maxrss_mb()
        with pytest.raises(ComponentError) as info:
            box.tools()
        grown = _maxrss_mb() - before
    finally:
        box.close()
    _assert_names_server_and_limit(str(info.value), hostile)
    print(f"tools/list gzip bomb: RSS high-water +{grown:.0f} MB")
    assert grown < 60


@pytest.mark.parametrize("mode", ["sse-endless", "sse-one-event"])
def test_an_endless_sse_answer_is_cut_at_the_limit(hostile: HostileMcpServer, mode: str) -> None:
    box = _box(hostile, timeout=30.0)
    try:
        (tool,) = box.tools()
        hostile.mode = mode
        start = time.monotonic()
        with pytest.raises(ComponentError) as info:
            tool(url="x")
        seconds = time.monotonic() - start
        _assert_names_server_and_limit(str(info.value), hostile)
        deadline = time.monotonic() + 10
        while hostile.streams_open and time.monotonic() < deadline:  # the client hung up: the stream ends
            time.sleep(0.05)
        assert hostile.streams_open == 0, "the client still reads the endless stream"
    finally:
        box.close()
    assert seconds < 10, f"cut after {seconds:.1f} s, not at the limit"
    # What the server got written before the client hung up: the limit plus what the sockets buffer.
    assert hostile.sent_after_refusal and max(hostile.sent_after_refusal) < LIMIT + 16 * 1024 * 1024


def test_an_endless_server_stream_is_cut_and_reopened_at_most_twice(hostile: HostileMcpServer) -> None:
    hostile.session = True
    box = _box(hostile)
    try:
        deadline = time.monotonic() + 20
        while (hostile.gets < 2 or hostile.streams_open) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert hostile.gets == 2 and hostile.streams_open == 0, (hostile.gets, hostile.streams_open)
        time.sleep(2.5)  # the SDK waits 1 s before it reopens: it gave up
        assert hostile.gets == 2 and hostile.streams_open == 0
        (tool,) = box.tools()
        assert tool(url="x") == "ok"  # the connection still serves
    finally:
        box.close()
    assert len(hostile.sent_after_refusal) == 2
    assert max(hostile.sent_after_refusal) < LIMIT + 16 * 1024 * 1024


def test_a_reply_of_exactly_the_limit_still_works_and_one_byte_more_is_refused(hostile: HostileMcpServer) -> None:
    box = _box(hostile, max_result_chars=2 * LIMIT)
    try:
        (tool,) = box.tools()
        hostile.mode, hostile.exact_bytes = "exact", LIMIT
        text = tool(url="x")
        assert len(text) > LIMIT - 200 and set(text) == {"a"}
        hostile.exact_bytes = LIMIT + 1
        with pytest.raises(ComponentError) as info:
            tool(url="x")
        _assert_names_server_and_limit(str(info.value), hostile)
    finally:
        box.close()


def test_the_llm_is_told_of_a_bomb_as_a_tool_error_naming_the_server_and_the_limit(
        hostile: HostileMcpServer) -> None:
    plan = [calls(("hostile__fetch", {"url": "x"})), lambda body: text("the tool failed")]
    question, answers = Topic("question", "String"), Topic("answer", "String")
    with ScriptedOllamaServer(plan=plan, models=["llama3.2:3b"]) as ollama:
        config = LLMConfig(mcp_servers=[{"target": hostile.url, "name": "hostile", "max_reply_bytes": LIMIT}])
        llm = LLM(inputs=[question], outputs=[answers], trigger=question, config=config, component_name="brain",
                  model_client=OllamaClient(OllamaModel(name="m", checkpoint="llama3.2:3b"), port=ollama.port))
        launcher = Launcher("memory")
        launcher.add_pkg(components=[llm])
        with launcher:
            got: list[str] = []
            sub = launcher.transport.create_subscription(answers, got.append)
            hostile.mode = "call-bomb"
            launcher.transport.create_publisher(question).publish("fetch x")
            assert wait_for(lambda: len(got) >= 1, 30)
            sub.close()
    told = [m for m in ollama.planning_requests[1]["messages"] if m.get("role") == "tool"][-1]["content"]
    assert told.startswith("error: ComponentError: MCP server 'hostile'"), told
    _assert_names_server_and_limit(told, hostile)


def test_the_cortex_refuses_a_bomb_listing_and_a_bomb_answer_naming_the_server(hostile: HostileMcpServer) -> None:
    spec = McpServerSpec(hostile.url, name="hostile", timeout=20.0, max_reply_bytes=LIMIT)
    tools, logger = ToolBox(), logging.getLogger("test.cortex")
    hostile.mode = "list-bomb"
    with pytest.raises(ComponentError) as info:
        connect_mcp_servers([spec], tools, [], logger)  # what the Cortex runs at configure
    _assert_names_server_and_limit(str(info.value), hostile)
    hostile.mode = "honest"
    boxes = connect_mcp_servers([spec], tools, [], logger)
    try:
        hostile.mode = "call-bomb"
        with pytest.raises(ComponentError) as info:
            call_mcp_tool(tools.get("hostile__fetch"), {"url": "x"})
        _assert_names_server_and_limit(str(info.value), hostile)
    finally:
        for box in boxes:
            box.close()


def test_max_reply_bytes_is_in_the_server_entry_with_a_default() -> None:
    assert McpServerSpec("http://127.0.0.1:1/mcp").max_reply_bytes == DEFAULT_MCP_MAX_REPLY_BYTES == 16 * 1024 * 1024
    assert server_spec({"target": "http://127.0.0.1:1/mcp", "max_reply_bytes": 4096}).max_reply_bytes == 4096
    for bad in (0, -1, True, 1.5, "16"):
        with pytest.raises(ConfigError, match="max_reply_bytes"):
            McpServerSpec("http://127.0.0.1:1/mcp", max_reply_bytes=bad)
