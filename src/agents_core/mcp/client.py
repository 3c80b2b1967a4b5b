"""Other MCP servers' tools for our models: ``LLMConfig(mcp_servers=[...])`` (the ``mcp`` extra).

Each entry of ``mcp_servers`` is a :class:`McpServerSpec` or what makes one: a URL
(``"http://127.0.0.1:3001/mcp"``: Streamable HTTP), a command line as a list
(``["npx", "-y", "@modelcontextprotocol/server-everything"]``: stdio), or a mapping of the spec's
fields. At configure the component connects (:class:`McpToolbox`, the official SDK's client on a
thread of its own), lists the server's tools and offers each to its model as
``<server name>__<tool name>``, under the same guardrails as our own actions
(:mod:`agents_core.guardrails`): ``allow`` (which tools are offered at all), ``limits`` (per tool,
per argument), ``approval`` (tools that wait for a person) and ``rate_limit``. Everything that
comes back is bounded: a call's time (``timeout``), the bytes of each HTTP reply after
decompression, streamed ones included (``max_reply_bytes``, :mod:`.bounded_http`), the text of its
result (``max_result_chars``), the number and size of the tool descriptions; a server that hangs,
dies or sends too much makes that call fail with a message the model sees, nothing more.
"""

from __future__ import annotations

import contextlib
import fnmatch
import json
import re
import threading
from collections.abc import Mapping, Sequence
from typing import Any

from attrs import define, field

from ..clients.reply_limit import check_max_reply_bytes
from ..errors import ComponentError, ConfigError
from ..guardrails import ActionGuard, run_guarded

__all__ = ["DEFAULT_MCP_MAX_REPLY_BYTES", "McpRemoteTool", "McpServerSpec", "McpToolbox", "server_spec"]

#: OpenAI-style tool names: what every model client accepts.
_MODEL_TOOL_NAME = re.compile(r"[^A-Za-z0-9_-]")
#: At most this many tools from one server; descriptions (as JSON) up to this many characters each.
MAX_TOOLS = 128
MAX_DESCRIPTION_CHARS = 20_000
#: The default ``max_reply_bytes`` of an HTTP server entry: 16 MiB of decoded reply per response.
DEFAULT_MCP_MAX_REPLY_BYTES = 16 * 1024 * 1024


def _target(value: Any) -> str | tuple[str, ...]:
    if isinstance(value, str):
        if not value.startswith(("http://", "https://")):
            raise ConfigError(f"an MCP server given as text must be an http(s) URL, got {value[:200]!r} "
                              "(a command is a list: ['npx', '-y', 'server'])")
        return value
    if isinstance(value, list | tuple) and value and all(isinstance(p, str) and p for p in value):
        return tuple(value)
    raise ConfigError(f"an MCP server is a URL or a command line (a list of strings), got {value!r}")


def _limits(value: Any) -> dict[str, dict[str, tuple[float, float]]]:
    if not isinstance(value, Mapping):
        raise ConfigError(f"MCP limits map tool names to {{argument: (low, high)}}, got {value!r}")
    return {str(tool): ActionGuard(limits=bounds).limits for tool, bounds in value.items()}


def _allow(value: Any) -> tuple[str, ...] | None:
    return None if value is None else tuple(str(v) for v in value)


def _positive(instance: Any, attribute: Any, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float) or not 0 < value <= 3600:
        raise ConfigError(f"McpServerSpec.{attribute.name}: expected seconds in (0, 3600], got {value!r}")


def _reply_bytes(instance: Any, attribute: Any, value: Any) -> None:
    check_max_reply_bytes("McpServerSpec", value)


@define(frozen=True)
class McpServerSpec:
    """One MCP server a model may use (see the module docs).

    :param target: the server's URL, or the command that starts it (stdio).
    :param name: the prefix of its tools' names (default: ``mcp``).
    :param allow: glob patterns of its tools to offer (None: all).
    :param limits: ``{tool: {argument: (low, high)}}``.
    :param approval: the tools each call of which waits for a person's yes.
    :param approval_timeout: seconds such a call waits before it is refused.
    :param rate_limit: ``(calls, seconds)`` per tool.
    :param timeout: seconds one call (or the connection) may take.
    :param max_result_chars: a result's text is cut past this.
    :param max_reply_bytes: the most bytes one HTTP reply of the server may carry after decompression
        (a JSON reply, or all of one SSE stream); past it that call fails naming the server and the limit.
    :param env: environment variables of a stdio server (a token, say: never logged).
    """

    target: str | tuple[str, ...] = field(converter=_target)
    name: str = "mcp"
    allow: tuple[str, ...] | None = field(default=None, converter=_allow)
    limits: dict[str, dict[str, tuple[float, float]]] = field(factory=dict, converter=_limits)
    approval: tuple[str, ...] = field(default=(), converter=tuple)
    approval_timeout: float = field(default=60.0, validator=_positive)
    rate_limit: tuple[int, float] | None = None
    timeout: float = field(default=30.0, validator=_positive)
    max_result_chars: int = 100_000
    max_reply_bytes: int = field(default=DEFAULT_MCP_MAX_REPLY_BYTES, validator=_reply_bytes)
    env: dict[str, str] | None = field(default=None, repr=False)

    def allowed(self, tool: str) -> bool:
        """Whether ``tool`` is offered."""
        return self.allow is None or any(fnmatch.fnmatchcase(tool, p) for p in self.allow)

    def guard(self, tool: str) -> ActionGuard:
        """The guardrails of ``tool``."""
        return ActionGuard(limits=self.limits.get(tool, {}), approval=tool in self.approval,
                           approval_timeout=self.approval_timeout, rate_limit=self.rate_limit)


def server_spec(value: Any) -> McpServerSpec:
    """An :class:`McpServerSpec` from a spec, a URL, a command list or a mapping of its fields."""
    if isinstance(value, McpServerSpec):
        return value
    if isinstance(value, Mapping):
        try:
            return McpServerSpec(**dict(value))
        except TypeError as exc:
            raise ConfigError(f"an MCP server mapping: {exc}") from None
    return McpServerSpec(value)


class McpRemoteTool:
    """One tool of an MCP server, callable by a model like a function (``tool(**arguments)``)."""

    def __init__(self, box: McpToolbox, remote_name: str, description: str, schema: dict[str, Any]) -> None:
        self._box, self.remote_name = box, remote_name
        spec = box.spec
        self.__name__ = _MODEL_TOOL_NAME.sub("_", f"{spec.name}__{remote_name}")[:64]
        self.component_name = f"mcp:{spec.name}"
        self.guard = spec.guard(remote_name)
        parameters = schema if isinstance(schema, dict) and schema.get("type") == "object" else {
            "type": "object", "properties": {}}
        properties = parameters.get("properties")
        for argument, (low, high) in self.guard.limits.items():
            entry = properties.get(argument) if isinstance(properties, dict) else None
            if isinstance(entry, dict):
                entry["minimum"], entry["maximum"] = low, high
        self.description: dict[str, Any] = {"type": "function", "function": {
            "name": self.__name__, "description": description[:2000], "parameters": parameters}}

        def invoke(self: McpRemoteTool, **arguments: Any) -> Any:
            return self._box.call(self.remote_name, arguments)

        invoke.__name__ = self.__name__
        self._invoke = invoke

    def __call__(self, **arguments: Any) -> Any:
        """Call the tool through its guardrails; its result's text (bounded)."""
        return run_guarded(self._invoke, self.guard, (self,), arguments)

    def __repr__(self) -> str:
        return f"McpRemoteTool({self.__name__!r})"


class McpToolbox:
    """A connection to one MCP server (the official SDK's client, on a thread of its own)."""

    def __init__(self, spec: McpServerSpec | Any) -> None:
        self.spec = server_spec(spec)
        self._portal: Any = None
        self._portal_cm: Any = None
        self._client: Any = None
        self._client_cm: Any = None
        self._lock = threading.Lock()

    def _where(self) -> str:
        target = self.spec.target
        return target if isinstance(target, str) else f"`{target[0]} ...`"

    def open(self) -> McpToolbox:
        """Connect (within ``spec.timeout``); ComponentError naming the server when it cannot."""
        from anyio.from_thread import start_blocking_portal  # noqa: PLC0415
        from mcp import Client, StdioServerParameters  # noqa: PLC0415

        from .bounded_http import bounded_streamable_http  # noqa: PLC0415  (the mcp extra)

        spec, target = self.spec, self.spec.target
        server: Any = (bounded_streamable_http(target, name=spec.name, max_reply_bytes=spec.max_reply_bytes)
                       if isinstance(target, str) else
                       StdioServerParameters(command=target[0], args=list(target[1:]), env=spec.env))
        self._portal_cm = start_blocking_portal()
        self._portal = self._portal_cm.__enter__()
        self._client_cm = self._portal.wrap_async_context_manager(
            Client(server, read_timeout_seconds=self.spec.timeout))
        entered: list[Any] = []
        failed: list[BaseException] = []

        def enter() -> None:
            try:
                entered.append(self._client_cm.__enter__())
            except BaseException as exc:  # reported below, with the server's name
                failed.append(exc)

        # The session is entered in the portal's own task (the SDK's task groups live there);
        # this thread only waits for it, within the spec's timeout.
        waiter = threading.Thread(target=enter, name=f"mcp-connect-{self.spec.name}", daemon=True)
        waiter.start()
        waiter.join(self.spec.timeout)
        if not entered:
            why = f"{type(failed[0]).__name__}: {failed[0]}" if failed else "no answer"
            self._client_cm = None  # not entered: nothing to exit
            self._abandon()
            raise ComponentError(f"MCP server {self.spec.name!r} ({self._where()}) did not connect within "
                                 f"{self.spec.timeout:g} s: {why}"[:600])
        self._client = entered[0]
        return self

    def _abandon(self) -> None:
        """Stop the portal, cancelling what still runs there (a connection that never answered)."""
        if self._portal_cm is not None:
            with contextlib.suppress(BaseException):
                self._portal_cm.__exit__(TimeoutError, TimeoutError(), None)
        self._portal = self._portal_cm = None

    async def _with_timeout(self, func: Any, *args: Any) -> Any:
        import anyio  # noqa: PLC0415

        with anyio.fail_after(self.spec.timeout):
            return await func(*args)

    def tools(self) -> list[McpRemoteTool]:
        """The server's tools that ``allow`` offers (at most :data:`MAX_TOOLS`)."""
        if self._client is None:
            raise ComponentError(f"MCP server {self.spec.name!r} is not connected")
        try:
            listed = self._portal.call(self._with_timeout, self._list)
        except TimeoutError:
            raise ComponentError(f"MCP server {self.spec.name!r}: tools/list did not answer within "
                                 f"{self.spec.timeout:g} s") from None
        except Exception as exc:
            raise ComponentError(f"MCP server {self.spec.name!r}: tools/list failed: {type(exc).__name__}: "
                                 f"{exc}"[:600]) from None
        found: list[McpRemoteTool] = []
        for tool in listed[:MAX_TOOLS]:
            schema = tool.input_schema if isinstance(tool.input_schema, dict) else {}
            if not self.spec.allowed(tool.name) or len(json.dumps(schema, default=str)) > MAX_DESCRIPTION_CHARS:
                continue
            found.append(McpRemoteTool(self, tool.name, tool.description or "", json.loads(json.dumps(schema))))
        return found

    async def _list(self) -> Any:
        return (await self._client.list_tools()).tools

    def call(self, tool: str, arguments: Mapping[str, Any]) -> str:
        """Call ``tool``; its result as text (cut at ``max_result_chars``); ComponentError when it fails."""
        if self._client is None:
            raise ComponentError(f"MCP server {self.spec.name!r} is not connected")
        try:
            with self._lock:  # one call at a time on this connection
                result = self._portal.call(self._with_timeout, self._call, tool, dict(arguments))
        except TimeoutError:
            raise ComponentError(f"MCP server {self.spec.name!r}: {tool} did not answer within "
                                 f"{self.spec.timeout:g} s") from None
        except Exception as exc:
            raise ComponentError(f"MCP server {self.spec.name!r}: {tool} failed: {type(exc).__name__}: "
                                 f"{exc}"[:600]) from None
        parts = [getattr(c, "text", None) or f"[{getattr(c, 'type', 'content')}]" for c in result.content]
        text = "\n".join(parts)
        if len(text) > self.spec.max_result_chars:
            text = text[:self.spec.max_result_chars] + f" ... [cut at {self.spec.max_result_chars} characters]"
        if result.is_error:
            raise ComponentError(f"MCP server {self.spec.name!r}: {tool} answered an error: {text[:1000]}")
        return text

    async def _call(self, tool: str, arguments: dict[str, Any]) -> Any:
        return await self._client.call_tool(tool, arguments)

    def close(self) -> None:
        """Disconnect (a stdio server's process ends); idempotent."""
        if self._client_cm is not None and self._portal is not None:
            with contextlib.suppress(BaseException):  # a server already gone: nothing more to close
                self._client_cm.__exit__(None, None, None)
        self._client = self._client_cm = None
        if self._portal_cm is not None:
            with contextlib.suppress(BaseException):
                self._portal_cm.__exit__(None, None, None)
        self._portal = self._portal_cm = None


def open_toolboxes(specs: Sequence[Any]) -> list[McpToolbox]:
    """Connect to each server of ``specs`` (closing those opened when one fails)."""
    opened: list[McpToolbox] = []
    try:
        for spec in specs:
            opened.append(McpToolbox(spec).open())
    except BaseException:
        for box in opened:
            box.close()
        raise
    return opened
