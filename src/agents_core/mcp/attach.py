"""The MCP server as a run attachment: ``launcher.enable_mcp()`` serves the recipe it launches.

:func:`mcp_options` checks what ``enable_mcp`` is given when it is given (off loopback a token is
needed: ``token=`` or ``AGENTS_MCP_TOKEN``) and registers the ``"mcp"`` attachment, which starts
an :class:`~agents_core.mcp.server.McpBridge` over the run's transport once every component is
active, serves Streamable HTTP at ``http://host:port/mcp`` and stops before the transport closes.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from ..errors import ConfigError
from ..launch.attachments import AttachmentKind, register_attachment

if TYPE_CHECKING:
    from ..components.component_base import Component
    from ..launch.report import LaunchReport
    from ..transport.contract import Transport
    from .server import McpHttpServer

__all__ = ["MCP_TOKEN_ENV_VAR", "mcp_options"]

#: Where the server's token is read from when ``enable_mcp`` is not given one (never from argv).
MCP_TOKEN_ENV_VAR = "AGENTS_MCP_TOKEN"


def mcp_options(host: str = "127.0.0.1", port: int = 5002, *, token: str | None = None,
                allow: Sequence[str] | None = None, components: Sequence[str] | None = None,
                tool_timeout: float = 30.0, approval_timeout: float = 60.0,
                audit_log: str | os.PathLike[str] | None = None) -> dict[str, Any]:
    """The ``"mcp"`` attachment's options (``Launcher.enable_mcp``), checked now; registers the attachment."""
    from .server import _is_loopback  # noqa: PLC0415

    token = token or os.environ.get(MCP_TOKEN_ENV_VAR) or None
    if not _is_loopback(host) and not token:
        raise ConfigError(f"enable_mcp(host={host!r}): off loopback the MCP server needs a token "
                          f"(token=..., or {MCP_TOKEN_ENV_VAR}); it does not start without one")
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise ConfigError(f"enable_mcp(port={port!r}): expected 0..65535")
    register_attachment(MCP_ATTACHMENT)
    return {"host": host, "port": port, "token": token, "allow": list(allow) if allow is not None else None,
            "components": list(components) if components is not None else None, "tool_timeout": tool_timeout,
            "approval_timeout": approval_timeout, "audit_log": str(audit_log) if audit_log is not None else None}


def _start(options: Mapping[str, Any], components: Sequence[Component], transport: Transport) -> McpHttpServer:
    from .server import McpBridge  # noqa: PLC0415  (the mcp extra)

    names = options["components"] or [c.component_name for c in components]
    bridge = McpBridge(transport, components=names, allow=options["allow"], tool_timeout=options["tool_timeout"],
                       approval_timeout=options["approval_timeout"], audit_log=options["audit_log"])
    return bridge.serve_http(options["host"], options["port"], options["token"])


def _announce(report: LaunchReport, server: McpHttpServer) -> None:
    report.line(f"agents: MCP at {server.url}")


MCP_ATTACHMENT = AttachmentKind("mcp", "after", _start, "start the MCP server", _announce)
