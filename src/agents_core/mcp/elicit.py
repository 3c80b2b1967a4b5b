"""Approvals asked of the MCP client that made the call (MCP elicitation), where that client can answer.

A tool whose action needs approval (``@component_action(approval=True)``), called by a client
that declared the ``elicitation`` capability: the bridge starts the call (its component holds it
under an approval id the bridge chose), asks the client a yes/no question naming the component,
the action and the arguments, and settles the held call through the component's ``approvals``
service. A yes runs it once; a no, a cancel, an error or no answer within the action's approval
time refuses it, and a refused call never runs late. The client is asked the way its protocol
version allows:

- sessions opened by the ``initialize`` handshake (2025 versions): an ``elicitation/create``
  request to the client while its ``tools/call`` is open;
- the 2026-07-28 per-request envelope: an ``input_required`` result carrying the elicitation.
  The client retries the call with its answer and the opaque ``requestState``: an unguessable
  handle of the held call kept here, good for that one call until it expires.

A client without the capability keeps the other ways to decide: ``agentsctl approve`` / ``deny``
and the web UI's approval panel. Every decision reaches the audit log with who made it.
"""

from __future__ import annotations

import json
import secrets
import threading
import time
import uuid
from typing import TYPE_CHECKING, Any

from ..errors import AgentsError

if TYPE_CHECKING:
    from .catalog import McpTool
    from .server import McpBridge

__all__ = ["APPROVAL_INPUT", "ApprovalAsker", "approval_question"]

#: The key of the approval question in an ``input_required`` result.
APPROVAL_INPUT = "approval"
#: At most this many calls wait for an ``input_required`` answer at once (each is a held call).
MAX_WAITING_ANSWERS = 64
_SCHEMA: dict[str, Any] = {
    "type": "object",
    "properties": {"approve": {"type": "boolean", "title": "Approve",
                               "description": "true runs the action once; false refuses it", "default": False}},
    "required": ["approve"],
}


def approval_question(component: str, action: str, arguments: Any, wait: float) -> str:
    """The text a person reads before saying yes or no."""
    try:
        shown = json.dumps(arguments, default=repr)
    except (TypeError, ValueError):
        shown = repr(arguments)
    if len(shown) > 1500:
        shown = shown[:1500] + "..."
    return (f"Approve {component}.{action} with {shown}? It runs once if you say yes; "
            f"without an answer within {wait:g} s it is refused.")


def _answer(value: Any) -> tuple[str, dict[str, Any]]:
    """An elicitation answer's (action, content), from the SDK's model or a plain mapping."""
    if isinstance(value, dict):
        action, content = value.get("action"), value.get("content")
    else:
        action, content = getattr(value, "action", None), getattr(value, "content", None)
    return str(action), dict(content) if isinstance(content, dict) else {}


def _said(value: Any) -> str:
    """What the answer said, for the audit log (``decline``, ``cancel``, ``approve: false``...)."""
    action, content = _answer(value)
    return f"approve: {json.dumps(content.get('approve'))[:20]}" if action == "accept" else action[:20]


def _approves(value: Any) -> bool:
    """Only an accepted answer whose ``approve`` is exactly true approves."""
    action, content = _answer(value)
    return action == "accept" and content.get("approve") is True


class _Held:
    """One call started on a thread of its own and held by its component until it is decided."""

    def __init__(self, bridge: McpBridge, tool: McpTool, arguments: Any) -> None:
        self.tool = tool
        self.call_id = uuid.uuid4().hex[:12]
        self.wait = bridge.approval_wait(tool)
        self.deadline = time.monotonic() + self.wait
        #: Added to the call's audit record (updated when the answer comes).
        self.approval: dict[str, Any] = {"approval": "elicitation", "approval_decision": "no answer in time"}
        self.done = threading.Event()
        self.result: Any = None
        self.error: str | None = None
        self._thread = threading.Thread(target=self._run, args=(bridge, arguments), daemon=True,
                                        name=f"mcp-held-{self.call_id}")
        self._thread.start()

    def _run(self, bridge: McpBridge, arguments: Any) -> None:
        try:
            self.result = bridge.call(self.tool.name, arguments, call_id=self.call_id, approval=self.approval)
        except AgentsError as exc:
            self.error = str(exc)
        except Exception as exc:  # reported to the client, never raised on this thread
            self.error = f"{type(exc).__name__}: {exc}"
        finally:
            self.done.set()

    def remaining(self) -> float:
        return max(0.0, self.deadline - time.monotonic())


class ApprovalAsker:
    """Asks the calling MCP client to approve held calls (see the module docs); one per :class:`McpBridge`."""

    def __init__(self, bridge: McpBridge) -> None:
        self._bridge = bridge
        self._lock = threading.Lock()
        self._waiting: dict[str, _Held] = {}  # requestState handle -> the held call

    @staticmethod
    def mode(ctx: Any) -> str | None:
        """How this request's client can be asked: ``"request"``, ``"input_required"`` or None (it cannot)."""
        from mcp_types.version import MODERN_PROTOCOL_VERSIONS  # noqa: PLC0415

        session = ctx.session
        capability = getattr(session.client_capabilities, "elicitation", None)
        if capability is None or (getattr(capability, "form", None) is None
                                  and getattr(capability, "url", None) is not None):
            return None  # no elicitation, or only URL mode (no form to say yes in)
        if session.protocol_version in MODERN_PROTOCOL_VERSIONS:
            return "input_required"
        return "request" if session.can_send_request else None

    def can_ask(self, ctx: Any, params: Any = None) -> bool:
        """Whether this call goes through :meth:`call` (the client can be asked, or is answering)."""
        return self.mode(ctx) is not None or getattr(params, "request_state", None) is not None

    async def call(self, ctx: Any, tool: McpTool, params: Any) -> Any:
        """Run ``tool`` asking its client for the approval; a ``CallToolResult`` (or ``InputRequiredResult``)."""
        import anyio  # noqa: PLC0415
        import mcp_types as types  # noqa: PLC0415

        if getattr(params, "request_state", None) is not None:
            return await self._resume(ctx, tool, params)
        held = _Held(self._bridge, tool, params.arguments)
        await anyio.to_thread.run_sync(self._until_held, held)
        if held.done.is_set():  # refused before it waited (limits, rate, a component not active)
            return self._result(held)
        question = types.ElicitRequestFormParams(
            message=approval_question(tool.component, tool.action, params.arguments or {}, held.wait),
            requested_schema=_SCHEMA)
        if self.mode(ctx) == "input_required":
            handle = secrets.token_urlsafe(24)
            with self._lock:
                self._prune()
                crowded = len(self._waiting) >= MAX_WAITING_ANSWERS
                if not crowded:
                    self._waiting[handle] = held
            if crowded:
                await self._settle(held, False, "agents-core (too many calls wait for an MCP answer)", "refused")
                return await self._finish(held)
            return types.InputRequiredResult(input_requests={APPROVAL_INPUT: types.ElicitRequest(params=question)},
                                             request_state=handle)
        who = self._who(ctx)
        try:
            with anyio.move_on_after(held.remaining()):  # no answer in time: the component refuses the call
                answer = await ctx.session.elicit_form(question.message, question.requested_schema,
                                                       related_request_id=ctx.request_id)
                await self._settle(held, _approves(answer), who, _said(answer))
        except Exception as exc:  # the client answered with an error: refused
            await self._settle(held, False, who, f"error: {type(exc).__name__}: {exc}"[:300])
        except BaseException:  # the MCP call was cancelled: the held call is refused with it
            with anyio.CancelScope(shield=True):
                await self._settle(held, False, who, "cancelled")
            raise
        return await self._finish(held)

    async def _resume(self, ctx: Any, tool: McpTool, params: Any) -> Any:
        """The client's retry carrying its answer (2026-07-28): settle the held call and return its result."""
        import mcp_types as types  # noqa: PLC0415

        handle = params.request_state
        with self._lock:
            held = self._waiting.pop(handle, None) if isinstance(handle, str) else None
        if held is None or held.tool.name != tool.name:
            if held is not None:  # an answer for another tool's call: that call is refused
                await self._settle(held, False, self._who(ctx), "answered for another tool")
            return types.CallToolResult(content=[types.TextContent(
                type="text", text=f"tool {tool.name!r}: no call waits for this answer (it expired or was "
                                  "settled); the action did not run")], is_error=True)
        responses = getattr(params, "input_responses", None) or {}
        answer = responses.get(APPROVAL_INPUT) if isinstance(responses, dict) else None
        if answer is None:
            await self._settle(held, False, self._who(ctx), "no answer")
        else:
            await self._settle(held, _approves(answer), self._who(ctx), _said(answer))
        return await self._finish(held)

    # -- the held call ----------------------------------------------------------------------

    def _until_held(self, held: _Held) -> None:
        """Wait (bounded by the approval time) until the component holds the call, or the call ended."""
        transport = self._bridge.catalog.transport
        while not held.done.is_set() and held.remaining() > 0:
            try:
                reply = transport.request(f"{held.tool.component}/approvals", {"op": "list"}, timeout=2.0)
            except AgentsError:
                reply = {}
            pending = reply.get("pending", []) if isinstance(reply, dict) else []
            if any(isinstance(c, dict) and c.get("id") == held.call_id for c in pending):
                return
            held.done.wait(0.05)

    async def _settle(self, held: _Held, approve: bool, who: str, answer: str) -> None:
        """Decide the held call through its component's ``approvals`` service (a no is a deny)."""
        import anyio  # noqa: PLC0415

        held.approval.update(approval_decision="approved" if approve else f"denied ({answer})", decided_by=who)
        transport = self._bridge.catalog.transport

        def decide() -> bool:
            try:
                reply = transport.request(f"{held.tool.component}/approvals",
                                          {"op": "decide", "id": held.call_id, "approve": approve, "by": who},
                                          timeout=5.0)
            except AgentsError:
                return False
            return isinstance(reply, dict) and bool(reply.get("decided"))

        if not await anyio.to_thread.run_sync(decide):
            held.approval["approval_decision"] = f"answered too late ({'yes' if approve else 'no'}): refused"

    async def _finish(self, held: _Held) -> Any:
        import anyio  # noqa: PLC0415

        await anyio.to_thread.run_sync(held.done.wait, held.remaining() + self._bridge.tool_timeout + 5.0)
        return self._result(held)

    @staticmethod
    def _result(held: _Held) -> Any:
        import mcp_types as types  # noqa: PLC0415

        from .server import _text  # noqa: PLC0415

        if not held.done.is_set():
            return types.CallToolResult(content=[types.TextContent(
                type="text", text=f"tool {held.tool.name!r}: no result in time")], is_error=True)
        if held.error is not None:
            return types.CallToolResult(content=[types.TextContent(type="text", text=_text(held.error))],
                                        is_error=True)
        return types.CallToolResult(content=[types.TextContent(type="text", text=_text(held.result))])

    def _prune(self) -> None:
        """Forget answers no longer awaited (the call ended: it timed out unanswered). Under the lock."""
        for handle in [h for h, held in self._waiting.items() if held.done.is_set()]:
            del self._waiting[handle]

    @staticmethod
    def _who(ctx: Any) -> str:
        params = getattr(ctx.session, "client_params", None)
        info = getattr(params, "client_info", None)
        name = getattr(info, "name", None)
        return f"mcp elicitation ({str(name)[:80]})" if name else "mcp elicitation"
