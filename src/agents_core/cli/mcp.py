"""``agentsctl mcp`` (serve a running recipe over MCP) and ``agentsctl approve`` / ``deny`` (decide held calls)."""

from __future__ import annotations

import os
import sys
import time
from typing import Annotated, Any

import typer

from ..errors import AgentsError, ConfigError
from .connection import discovery_timeout, fail, one_line_errors, open_transport
from .output import print_json, say

__all__ = ["approve", "deny", "mcp"]

#: Where ``agentsctl mcp --http`` off loopback reads its token (never from the command line).
MCP_TOKEN_ENV_VAR = "AGENTS_MCP_TOKEN"

TransportOption = Annotated[str | None, typer.Option("--transport", "-t", help="zenoh or ros2 (default: "
                                                     "AGENTS_TRANSPORT, else zenoh)")]
ConnectOption = Annotated[list[str] | None, typer.Option("--connect", help="Zenoh endpoint of a router or peer "
                                                         "(repeatable)")]


@one_line_errors
def mcp(transport: TransportOption = None, connect: ConnectOption = None,
        component: Annotated[list[str] | None, typer.Option("--component", help="offer only these components "
                                                              "(repeatable)")] = None,
        allow: Annotated[list[str] | None, typer.Option("--allow", help="tool name patterns MCP may offer, e.g. "
                                                         "'arm__*' (repeatable; default: all)")] = None,
        http: Annotated[bool, typer.Option("--http", help="serve Streamable HTTP instead of stdio")] = False,
        host: Annotated[str, typer.Option(help="--http bind address (off loopback needs AGENTS_MCP_TOKEN)")]
        = "127.0.0.1",
        port: Annotated[int, typer.Option(help="--http port")] = 5002,
        approval_timeout: Annotated[float, typer.Option(help="the longest a call waits for approval (s)")] = 60.0,
        audit_log: Annotated[str | None, typer.Option(help="the audit file (one JSON record a line; default "
                                                      "~/.local/state/agents_core/audit.jsonl)")] = None,
        seconds: Annotated[float, typer.Option(help="--http: stop after this long (0: until Ctrl+C)")] = 0.0,
        ) -> None:
    """Serve a recipe running elsewhere over MCP: on stdin/stdout (what AI clients start) or --http."""
    from ..mcp import McpBridge  # noqa: PLC0415

    with open_transport(transport, connect) as opened:
        bridge = McpBridge(opened, components=component, allow=allow, approval_timeout=approval_timeout,
                           audit_log=audit_log)
        if not http:
            bridge.serve_stdio()  # stdout is the protocol's: nothing else may print there
            return
        server = bridge.serve_http(host, port, os.environ.get(MCP_TOKEN_ENV_VAR) or None)
        say(f"MCP for the recipe on {opened.name}: {server.url}")
        try:
            deadline = time.monotonic() + seconds if seconds > 0 else None
            while deadline is None or time.monotonic() < deadline:
                time.sleep(0.2)
        except KeyboardInterrupt:
            pass
        finally:
            server.stop()


def _pending(opened: Any, timeout: float) -> list[tuple[str, dict[str, Any]]]:
    found: list[tuple[str, dict[str, Any]]] = []
    seen: set[str] = set()
    for name in sorted(opened.discover(timeout=timeout).components):
        try:
            reply = opened.request(f"{name}/approvals", {"op": "list"}, timeout=timeout)
        except AgentsError:
            continue  # a component of an older version, or gone
        for call in reply.get("pending", []) if isinstance(reply, dict) else []:
            if isinstance(call, dict) and isinstance(call.get("id"), str) and call["id"] not in seen:
                seen.add(call["id"])
                found.append((name, call))
    return found


def _decide(approve_it: bool, call_id: str | None, every: bool, transport: str | None, connect: list[str] | None,
            timeout: float | None, as_json: bool) -> None:
    with open_transport(transport, connect) as opened:
        wait = discovery_timeout(opened, timeout)
        pending = _pending(opened, wait)
        if call_id is None and not every:
            if not pending:
                raise fail("no call waits for approval")
            if len(pending) > 1:
                listing = "; ".join(f"{c['id']}: {c['component']}.{c['action']}({c['arguments']})" for _, c in pending)
                raise fail(f"{len(pending)} calls wait ({listing}): give an id, or --all")
        chosen = pending if every or call_id is None else [(n, c) for n, c in pending if c["id"] == call_id]
        if not chosen:
            raise ConfigError(f"no call {call_id!r} waits for approval; waiting: {[c['id'] for _, c in pending]}")
        who = f"agentsctl ({os.environ.get('USER', 'operator')})"
        done = []
        for name, call in chosen:
            reply = opened.request(f"{name}/approvals", {"op": "decide", "id": call["id"], "approve": approve_it,
                                                         "by": who}, timeout=wait)
            done.append({**call, "decided": bool(reply.get("decided"))})
        if as_json:
            print_json(done)
            return
        verb = "approved" if approve_it else "denied"
        for call in done:
            say(f"{verb if call['decided'] else 'too late for'} {call['id']}: {call['component']}.{call['action']}")


CallId = Annotated[str | None, typer.Argument(help="the held call's id (default: the one call waiting)")]
AllOption = Annotated[bool, typer.Option("--all", help="every held call")]
TimeoutOption = Annotated[float | None, typer.Option(help="seconds to find the components")]
JsonOption = Annotated[bool, typer.Option("--json", help="print JSON")]


@one_line_errors
def approve(call_id: CallId = None, every: AllOption = False, transport: TransportOption = None,
            connect: ConnectOption = None, timeout: TimeoutOption = None, as_json: JsonOption = False) -> None:
    """Approve a call held by its action's guardrails (approval=True)."""
    _decide(True, call_id, every, transport, connect, timeout, as_json)


@one_line_errors
def deny(call_id: CallId = None, every: AllOption = False, transport: TransportOption = None,
         connect: ConnectOption = None, timeout: TimeoutOption = None, as_json: JsonOption = False) -> None:
    """Deny a call held by its action's guardrails (it never runs)."""
    _decide(False, call_id, every, transport, connect, timeout, as_json)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(typer.run(mcp))  # type: ignore[func-returns-value]
