"""The web UI's approval panel API: the calls held for a person's yes, and the decisions.

- ``GET /api/approvals``: ``{"pending": [{"id", "component", "action", "arguments", "caller",
  "waiting_s", "expires_in_s", "holder"}, ...]}``, oldest first: every call held by an action's
  ``approval=True`` guardrail in the components the UI shows (each component's ``approvals``
  service; ``holder`` is the component that answered, the one the decision goes to).
- ``POST /api/approvals/{id}`` with ``{"approve": true | false}``: settles the held call through
  the same service (``agentsctl approve`` / ``deny`` and MCP elicitation use it too); 404 when no
  such call waits (decided, timed out or never there), 422 for a body without a boolean
  ``approve``. The decision is recorded as made by ``web UI (<client address>)``.

The page polls the list about once a second and counts each call's time down between polls.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import TYPE_CHECKING, Any

from ..errors import AgentsError

if TYPE_CHECKING:
    from starlette.requests import HTTPConnection, Request
    from starlette.responses import Response

__all__ = ["approval_routes", "held_calls"]

Endpoint = Callable[["Request"], Awaitable["Response"]]
#: The most held calls listed at once (a broker holds at most 256 per process).
MAX_LISTED = 256
#: Seconds each component may take to answer a list or a decision.
ASK_TIMEOUT = 2.0


def held_calls(state: Any) -> list[dict[str, Any]]:
    """Every call waiting for approval in the components of ``state`` (the UI's ``UIState``: its
    view, transport and settings), oldest first (each listed once)."""
    found: dict[str, dict[str, Any]] = {}
    wait = min(ASK_TIMEOUT, state.settings.request_timeout)
    for name in state.view.component_names():
        try:
            reply = state.transport.request(f"{name}/approvals", {"op": "list"}, timeout=wait)
        except AgentsError:
            continue  # gone, not active, or a component of an older version
        pending = reply.get("pending") if isinstance(reply, dict) else None
        for call in pending if isinstance(pending, list) else []:
            if isinstance(call, dict) and isinstance(call.get("id"), str) and call["id"] not in found:
                found[call["id"]] = {**call, "holder": name}  # components of one process share their calls
    listed = sorted(found.values(), key=lambda c: -float(c.get("waiting_s") or 0.0))
    return listed[:MAX_LISTED]


def _decide(state: Any, call_id: str, approve: bool, by: str) -> bool:
    for call in held_calls(state):
        if call["id"] == call_id:
            reply = state.transport.request(f"{call['holder']}/approvals",
                                            {"op": "decide", "id": call_id, "approve": approve, "by": by},
                                            timeout=min(ASK_TIMEOUT, state.settings.request_timeout))
            return isinstance(reply, dict) and bool(reply.get("decided"))
    return False


def approval_routes(state: Any, guarded: Callable[[Endpoint], Endpoint],
                    json_body: Callable[[Request], Awaitable[dict[str, Any]]],
                    address: Callable[[HTTPConnection], str]) -> list[Any]:
    """The two routes of the panel (each behind the UI's token and origin checks: ``guarded``)."""
    from starlette.concurrency import run_in_threadpool  # noqa: PLC0415
    from starlette.responses import JSONResponse  # noqa: PLC0415
    from starlette.routing import Route  # noqa: PLC0415

    async def listing(request: Request) -> Response:
        return JSONResponse({"pending": await run_in_threadpool(held_calls, state)})

    async def decide(request: Request) -> Response:
        call_id = request.path_params["call_id"]
        approve = (await json_body(request)).get("approve")
        if not isinstance(approve, bool):
            return JSONResponse({"error": f"'approve' must be true or false, got {approve!r}"[:300]}, status_code=422)
        by = f"web UI ({address(request)})"
        try:
            decided = await run_in_threadpool(_decide, state, call_id, approve, by)
        except AgentsError as exc:
            return JSONResponse({"error": f"approval {call_id[:64]!r}: {exc}"[:500]}, status_code=503)
        if not decided:
            return JSONResponse({"error": f"no call {call_id[:64]!r} waits for approval (decided or timed out)"},
                                status_code=404)
        return JSONResponse({"ok": True, "id": call_id, "approved": approve, "by": by})

    return [Route("/api/approvals", guarded(listing)),
            Route("/api/approvals/{call_id}", guarded(decide), methods=["POST"])]
