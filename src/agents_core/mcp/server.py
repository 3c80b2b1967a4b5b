"""A running recipe served over MCP (the official ``mcp`` SDK's low-level server): Streamable HTTP or stdio.

:class:`McpBridge` answers MCP's tool and resource requests from a :class:`~.catalog.RecipeCatalog`;
:meth:`McpBridge.serve_http` serves it at ``http://host:port/mcp`` on a thread of its own and
:meth:`McpBridge.serve_stdio` on this process's standard streams (what desktop AI clients start:
``agentsctl mcp``). Over HTTP it binds loopback by default; any other address needs a token
(``Authorization: Bearer <token>``, compared in constant time) and refuses to start without one.
Browsers' requests are refused unless their ``Origin`` is the server's own (the web UI's rule),
request bodies are bounded, sessions are capped and expire when idle (the SDK's settings).

Every call reaches the action through its component's ``execute_method`` with the caller
``"mcp"``: its guardrails (limits, rate, approval) and the audit log run there.
"""

from __future__ import annotations

import base64
import contextlib
import hmac
import ipaddress
import json
import logging
import os
import threading
import time
import uuid
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import AgentsError, ConfigError

if TYPE_CHECKING:
    from ..transport.contract import Transport
    from .catalog import McpTool, RecipeCatalog

__all__ = ["AUDIT_TOPIC", "DEFAULT_MCP_PORT", "McpBridge", "McpHttpServer", "default_audit_path"]

logger = logging.getLogger(__name__)

#: The port ``enable_mcp`` / ``agentsctl mcp --http`` serve on unless told otherwise.
DEFAULT_MCP_PORT = 5002
#: The longest JSON-RPC body accepted (bytes).
MAX_BODY_BYTES = 1 << 20
#: At most this many MCP sessions at once; idle ones end after SESSION_IDLE_S.
MAX_SESSIONS = 64
SESSION_IDLE_S = 300.0
#: Resource-updated events a topic may cause per second (a 30 Hz camera must not flood clients).
EVENTS_PER_S = 10.0
#: A tool result longer than this (characters) is cut, saying so.
MAX_RESULT_CHARS = 200_000

#: The topic each MCP call's audit record is published on (JSON in a String).
AUDIT_TOPIC = "audit"

RECIPE_URI = "agents://recipe"
HEALTH_URI = "agents://health"
TOPIC_URI = "agents://topic/"


def default_audit_path() -> Path:
    """Where MCP's audit records go unless told: ``$XDG_STATE_HOME/agents_core/audit.jsonl``
    (``~/.local/state/agents_core/audit.jsonl``)."""
    state = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(state) / "agents_core" / "audit.jsonl"


def _is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _text(value: Any) -> str:
    text = value if isinstance(value, str) else json.dumps(value, default=repr)
    return text if len(text) <= MAX_RESULT_CHARS else text[:MAX_RESULT_CHARS] + f"... [cut at {MAX_RESULT_CHARS}]"


class _LatestValues:
    """The newest value of each output topic, subscribed on first read (bounded: one value a topic)."""

    def __init__(self, transport: Transport, on_change: Any = None) -> None:
        self._transport = transport
        self._lock = threading.Lock()
        self._values: dict[str, tuple[str, Any, float]] = {}
        self._subscriptions: dict[str, Any] = {}
        self._on_change = on_change  # called with the topic's name (from the transport's thread)

    def ensure(self, name: str, type_name: str) -> None:
        from ..topics import Topic  # noqa: PLC0415

        with self._lock:
            if name in self._subscriptions:
                return
            self._subscriptions[name] = None

        def keep(value: Any) -> None:
            with self._lock:
                self._values[name] = (type_name, value, time.time())
            if self._on_change is not None:
                self._on_change(name)

        try:
            subscription = self._transport.create_subscription(Topic(name, type_name), keep)
        except AgentsError:
            with self._lock:
                self._subscriptions.pop(name, None)
            raise
        with self._lock:
            self._subscriptions[name] = subscription

    def latest(self, name: str) -> tuple[str, Any, float] | None:
        with self._lock:
            return self._values.get(name)

    def close(self) -> None:
        with self._lock:
            subscriptions, self._subscriptions = list(self._subscriptions.values()), {}
        for subscription in subscriptions:
            if subscription is not None:
                subscription.close()


class McpBridge:
    """MCP's tools and resources for the recipe ``transport`` reaches (see the module docs).

    :param components: the components to offer (None: every one discovered).
    :param allow: glob patterns of the tool names MCP may offer (None: every action).
    :param tool_timeout: seconds an action may run.
    :param approval_timeout: the longest an action that needs approval waits for it (seconds; at most 60 by default).
    """

    def __init__(self, transport: Transport, *, components: Sequence[str] | None = None,
                 allow: Sequence[str] | None = None, tool_timeout: float = 30.0,
                 approval_timeout: float = 60.0, audit_log: str | os.PathLike[str] | None = None,
                 audit_topic: str | None = AUDIT_TOPIC, name: str = "agents-core") -> None:
        from ..guardrails import audit_log as process_audit_log  # noqa: PLC0415
        from .catalog import RecipeCatalog  # noqa: PLC0415

        for label, value in (("tool_timeout", tool_timeout), ("approval_timeout", approval_timeout)):
            if isinstance(value, bool) or not isinstance(value, int | float) or not 0 < value <= 3600:
                raise ConfigError(f"MCP {label} must be seconds in (0, 3600], got {value!r}")
        self.catalog: RecipeCatalog = RecipeCatalog(transport, components=components, allow=allow)
        self.tool_timeout = float(tool_timeout)
        self.approval_timeout = float(approval_timeout)
        self._latest = _LatestValues(transport, self._topic_changed)
        self._loop_token: Any = None  # the serving event loop's, for events sent from transport threads
        self._bus: Any = None
        self._last_event: dict[str, float] = {}
        self._audit = process_audit_log()
        self._audit_before = self._audit.path  # restored at close: the bridge borrows the process's log
        if audit_log is not None or self._audit.path is None:
            self._audit.configure(audit_log if audit_log is not None else default_audit_path())
        self._audit_publisher: Any = None
        if audit_topic:
            from ..topics import Topic  # noqa: PLC0415

            self._audit_publisher = transport.create_publisher(Topic(audit_topic, "String"))
        from .elicit import ApprovalAsker  # noqa: PLC0415

        self._asker = ApprovalAsker(self)
        self.server = self._build(name)

    # -- the MCP server ---------------------------------------------------------------------

    def _build(self, name: str) -> Any:
        import anyio  # noqa: PLC0415
        import mcp_types as types  # noqa: PLC0415
        from mcp.server.lowlevel import Server  # noqa: PLC0415

        from .. import __version__  # noqa: PLC0415

        async def list_tools(ctx: Any, params: Any) -> Any:
            tools = await anyio.to_thread.run_sync(self.catalog.tools)
            return types.ListToolsResult(tools=[self._tool(t) for t in tools])

        async def call_tool(ctx: Any, params: Any) -> Any:
            try:
                tool = await anyio.to_thread.run_sync(self.catalog.find, params.name)
                if tool.goal_type is not None:
                    return await self._run_goal(ctx, tool, params.arguments)
                if self.approval_wait(tool) and self._asker.can_ask(ctx, params):
                    return await self._asker.call(ctx, tool, params)  # the client asks its user
                result = await anyio.to_thread.run_sync(self.call, params.name, params.arguments)
            except AgentsError as exc:
                return types.CallToolResult(content=[types.TextContent(type="text", text=_text(str(exc)))],
                                            is_error=True)
            return types.CallToolResult(content=[types.TextContent(type="text", text=_text(result))])

        async def list_resources(ctx: Any, params: Any) -> Any:
            topics = await anyio.to_thread.run_sync(self.catalog.output_topics)
            resources = [types.Resource(name="recipe", uri=RECIPE_URI, mime_type="application/json",
                                        description="every component: type, state, topics and actions"),
                         types.Resource(name="health", uri=HEALTH_URI, mime_type="application/json",
                                        description="each component's lifecycle state and health")]
            resources += [types.Resource(name=f"topic {topic}", uri=TOPIC_URI + topic,
                                         description=f"the latest value on {topic} ({kind})")
                          for topic, kind in sorted(topics.items())]
            return types.ListResourcesResult(resources=resources)

        async def read_resource(ctx: Any, params: Any) -> Any:
            uri = str(params.uri)
            mime, payload = await anyio.to_thread.run_sync(self.read, uri)
            if isinstance(payload, bytes):
                return types.ReadResourceResult(contents=[types.BlobResourceContents(
                    uri=uri, mime_type=mime, blob=base64.b64encode(payload).decode("ascii"))])
            return types.ReadResourceResult(contents=[types.TextResourceContents(uri=uri, mime_type=mime,
                                                                                 text=payload)])

        from mcp.server.subscriptions import InMemorySubscriptionBus, ListenHandler  # noqa: PLC0415

        self._bus = InMemorySubscriptionBus()
        listen = ListenHandler(self._bus, max_subscriptions=MAX_SESSIONS * 4, max_buffered_events=256)

        async def subscriptions_listen(ctx: Any, params: Any) -> Any:
            self._loop_token = anyio.lowlevel.current_token()
            wanted = list(getattr(params.notifications, "resource_subscriptions", None) or [])
            topics = await anyio.to_thread.run_sync(self.catalog.output_topics)
            for uri in wanted[:64]:
                topic = str(uri)[len(TOPIC_URI):] if str(uri).startswith(TOPIC_URI) else None
                if topic in topics:
                    await anyio.to_thread.run_sync(self._latest.ensure, topic, topics[topic])
            return await listen(ctx, params)

        return Server(name, version=__version__, on_list_tools=list_tools, on_call_tool=call_tool,
                      on_list_resources=list_resources, on_read_resource=read_resource,
                      on_subscriptions_listen=subscriptions_listen)

    def _topic_changed(self, topic: str) -> None:
        """A new value on ``topic``: tell listening clients (at most EVENTS_PER_S a topic; newest wins)."""
        token, bus = self._loop_token, self._bus
        now = time.monotonic()
        if token is None or bus is None or now - self._last_event.get(topic, 0.0) < 1.0 / EVENTS_PER_S:
            return
        self._last_event[topic] = now
        import anyio.from_thread  # noqa: PLC0415
        from mcp.shared.subscriptions import ResourceUpdated  # noqa: PLC0415

        try:
            anyio.from_thread.run(bus.publish, ResourceUpdated(uri=TOPIC_URI + topic), token=token)
        except Exception:  # the loop stopped (the server is closing): nobody listens any more
            self._loop_token = None

    async def _run_goal(self, ctx: Any, tool: McpTool, arguments: dict[str, Any] | None) -> Any:
        """Send the goal; its feedback as progress notifications; cancel it when the MCP call is cancelled."""
        import queue  # noqa: PLC0415

        import anyio  # noqa: PLC0415
        import mcp_types as types  # noqa: PLC0415

        from .catalog import check_arguments  # noqa: PLC0415

        goal = dict(arguments or {})
        check_arguments(tool, goal)
        feedback: queue.Queue[dict[str, Any]] = queue.Queue(maxsize=256)

        def on_feedback(value: dict[str, Any]) -> None:
            with contextlib.suppress(queue.Full):  # a client slower than the feedback: later ones come
                feedback.put_nowait(value)

        transport = self.catalog.transport
        client = await anyio.to_thread.run_sync(
            lambda: transport.send_goal(tool.component, str(tool.goal_type), goal, feedback=on_feedback,
                                        timeout=self.tool_timeout))
        self._write_audit({"caller": "mcp", "tool": tool.name, "arguments": _text(goal)[:2000],
                           "decision": "allowed", "outcome": f"goal {client.status.name.lower()}"})
        sent = 0
        try:
            while not client.done:
                await anyio.sleep(0.05)
                while not feedback.empty():
                    sent += 1
                    await ctx.session.report_progress(float(sent), None, _text(feedback.get_nowait())[:2000])
            status, result = await anyio.to_thread.run_sync(client.result, self.tool_timeout)
        except BaseException:
            # The MCP call was cancelled (or the client went away): the robot stops too.
            with anyio.CancelScope(shield=True):
                await anyio.to_thread.run_sync(client.cancel)
            raise
        text = _text({"status": status.name.lower(), "result": result})
        return types.CallToolResult(content=[types.TextContent(type="text", text=text)],
                                    is_error=status.name != "SUCCEEDED")

    @staticmethod
    def _tool(tool: McpTool) -> Any:
        import mcp_types as types  # noqa: PLC0415

        description = tool.description or f"{tool.action} of {tool.component}"
        return types.Tool(name=tool.name, description=description, input_schema=tool.input_schema,
                          _meta={"agents-core/guardrails": tool.guardrails} if tool.guardrails else None)

    # -- what the handlers do (blocking: they run on worker threads) --------------------------

    def call(self, name: str, arguments: dict[str, Any] | None, *, call_id: str | None = None,
             approval: dict[str, Any] | None = None) -> Any:
        """Run the tool ``name``; AgentsError when it is unknown, refused or fails (each call audited).

        ``call_id``: the approval id of the held call (an elicitation decides it); ``approval``:
        how it was decided (filled in while the call waits; added to the audit record).
        """
        from ..guardrails import GuardrailRefused  # noqa: PLC0415

        record: dict[str, Any] = {"caller": "mcp", "tool": str(name)[:200],
                                  "arguments": _text(arguments)[:2000] if arguments is not None else None}
        try:
            result = self._call(name, arguments, call_id)
        except (GuardrailRefused, ConfigError) as exc:
            self._write_audit({**record, **(approval or {}), "decision": "refused", "outcome": str(exc)[:500]})
            raise
        except AgentsError as exc:
            refused = "did not run" in str(exc) or "denied" in str(exc)
            self._write_audit({**record, **(approval or {}), "decision": "refused" if refused else "allowed",
                               "outcome": f"error: {exc}"[:500]})
            raise
        self._write_audit({**record, **(approval or {}), "decision": "allowed", "outcome": "ok"})
        return result

    def _write_audit(self, record: dict[str, Any]) -> None:
        self._audit.write(record)
        if self._audit_publisher is not None:
            try:
                self._audit_publisher.publish(json.dumps({"time": time.time(), **record}, default=repr))
            except AgentsError:
                logger.warning("audit record not published on the audit topic")

    def approval_wait(self, tool: McpTool) -> float:
        """The longest a call of ``tool`` waits for its approval (0: it needs none)."""
        if not tool.guardrails.get("approval"):
            return 0.0
        return min(self.approval_timeout, float(tool.guardrails.get("approval_timeout", self.approval_timeout)))

    def _call(self, name: str, arguments: dict[str, Any] | None, call_id: str | None = None) -> Any:
        tool = self.catalog.find(name)
        state = self.catalog.state(tool.component)
        if state != "active":
            # A robot's action must not run half-way in a component that is stopping or stopped.
            raise ConfigError(f"tool {name!r}: component {tool.component!r} is {state}, not active; not run")
        if arguments is not None and not isinstance(arguments, dict):
            raise ConfigError(f"tool {name!r}: arguments must be an object")
        wait = self.approval_wait(tool)
        return self.catalog.call(tool, arguments, timeout=self.tool_timeout + wait,
                                 call_id=(call_id or uuid.uuid4().hex[:12]) if wait else None,
                                 approval_timeout=wait if wait else None)

    def read(self, uri: str) -> tuple[str, str | bytes]:
        """A resource's (mime type, text or bytes)."""
        from ..ui.frames import image_bytes, jsonable  # noqa: PLC0415  (no web server needed)

        if uri == RECIPE_URI:
            return "application/json", json.dumps(jsonable(self.catalog.descriptions()))
        if uri == HEALTH_URI:
            return "application/json", json.dumps(jsonable(self.catalog.health()))
        if uri.startswith(TOPIC_URI):
            topic = uri[len(TOPIC_URI):]
            topics = self.catalog.output_topics()
            if topic not in topics:
                raise ConfigError(f"no topic {topic[:200]!r} among the recipe's outputs {sorted(topics)[:50]}")
            self._latest.ensure(topic, topics[topic])
            latest = self._latest.latest(topic)
            if latest is None:
                return "application/json", json.dumps({"topic": topic, "value": None, "note": "no value yet"})
            kind, value, stamp = latest
            if kind in ("Image", "CompressedImage"):
                mime, data, *_ = image_bytes(value)
                return mime, data
            return "application/json", json.dumps({"topic": topic, "type": kind, "received": stamp,
                                                   "value": jsonable(value)})
        raise ConfigError(f"no resource {uri[:200]!r}")

    def close(self) -> None:
        """Drop the topic subscriptions and the audit publisher (the caller closes the transport)."""
        self._latest.close()
        self._audit.configure(self._audit_before)
        if self._audit_publisher is not None:
            self._audit_publisher.close()
            self._audit_publisher = None

    # -- serving ------------------------------------------------------------------------------

    def serve_stdio(self) -> None:
        """Serve MCP on stdin/stdout until the client closes them (blocks)."""
        import anyio  # noqa: PLC0415
        from mcp.server.stdio import stdio_server  # noqa: PLC0415

        async def main() -> None:
            async with stdio_server() as (read, write):
                await self.server.run(read, write, self.server.create_initialization_options())

        anyio.run(main)

    def serve_http(self, host: str = "127.0.0.1", port: int = DEFAULT_MCP_PORT,
                   token: str | None = None) -> McpHttpServer:
        """Serve Streamable HTTP at ``http://host:port/mcp`` on a thread; the running server (``url``, ``stop()``)."""
        return McpHttpServer(self, host, port, token).start()


class McpHttpServer:
    """The bridge's Streamable HTTP endpoint, run by uvicorn on a thread of its own."""

    def __init__(self, bridge: McpBridge, host: str, port: int, token: str | None) -> None:
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise ConfigError(f"MCP port must be 0..65535, got {port!r}")
        if not _is_loopback(host) and not token:
            raise ConfigError(f"MCP on {host!r} (off loopback) needs a token: set AGENTS_MCP_TOKEN or pass token=")
        if token is not None and (not isinstance(token, str) or len(token) < 16):
            raise ConfigError("the MCP token must be a string of at least 16 characters")
        self.bridge, self.host, self.port, self._token = bridge, host, port, token
        self._server: Any = None
        self._thread: threading.Thread | None = None

    def __repr__(self) -> str:  # never the token
        return f"McpHttpServer({self.url!r}, token={'set' if self._token else 'none'})"

    @property
    def url(self) -> str:
        """Where clients connect."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/mcp"

    def _app(self) -> Any:
        from mcp.server.transport_security import TransportSecuritySettings  # noqa: PLC0415

        # Browsers may only come from the server's own origin (no other page can drive the robot).
        own = [f"{self.host}:{self.port}", f"{self.host}:*"]
        if _is_loopback(self.host):
            own += ["127.0.0.1:*", "localhost:*", "[::1]:*"]
        security = TransportSecuritySettings(enable_dns_rebinding_protection=True, allowed_hosts=own,
                                             allowed_origins=[f"http://{h}" for h in own])
        app = self.bridge.server.streamable_http_app(
            host=self.host, transport_security=security, max_request_body_size=MAX_BODY_BYTES,
            max_sessions=MAX_SESSIONS, session_idle_timeout=SESSION_IDLE_S)
        return _BearerGuard(app, self._token) if self._token else app

    def start(self) -> McpHttpServer:
        """Bind and serve; returns once the port is open (``port=0`` picks a free one)."""
        import socket  # noqa: PLC0415

        import uvicorn  # noqa: PLC0415  (the ui extra's server)

        sock = socket.socket(socket.AF_INET6 if ":" in self.host else socket.AF_INET)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((self.host, self.port))
        self.port = sock.getsockname()[1]
        config = uvicorn.Config(self._app(), log_level="warning", lifespan="on", timeout_keep_alive=5,
                                limit_concurrency=256, h11_max_incomplete_event_size=64 * 1024)
        self._server = uvicorn.Server(config)
        self._thread = threading.Thread(target=self._server.run, kwargs={"sockets": [sock]},
                                        name="agents-mcp-http", daemon=True)
        self._thread.start()
        deadline = time.monotonic() + 10.0
        while not self._server.started and self._thread.is_alive() and time.monotonic() < deadline:
            time.sleep(0.01)
        if not self._server.started:
            raise ConfigError(f"the MCP server did not start on {self.url}")
        logger.info("MCP on %s", self.url)
        return self

    def stop(self) -> None:
        """Stop serving (idempotent)."""
        if self._server is not None:
            self._server.should_exit = True
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        self.bridge.close()


class _BearerGuard:
    """ASGI middleware: HTTP requests without ``Authorization: Bearer <token>`` get 401."""

    def __init__(self, app: Any, token: str) -> None:
        self.app, self._token = app, token.encode("utf-8")

    async def __call__(self, scope: dict[str, Any], receive: Any, send: Any) -> None:
        if scope["type"] == "http":
            given = b""
            for key, value in scope.get("headers", []):
                if key == b"authorization" and value[:7].lower() == b"bearer ":
                    given = value[7:].strip()
            if not hmac.compare_digest(given, self._token):
                await send({"type": "http.response.start", "status": 401,
                            "headers": [(b"content-type", b"application/json"), (b"www-authenticate", b"Bearer")]})
                await send({"type": "http.response.body", "body": b'{"error": "a valid bearer token is needed"}'})
                return
        await self.app(scope, receive, send)
