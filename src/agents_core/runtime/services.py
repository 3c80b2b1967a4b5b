"""The services every component serves: ``<name>/execute_method``, ``<name>/set_param`` and ``<name>/describe``.

``describe`` answers what the component is (type, run type, state, health, inputs, outputs,
callable actions), for tools such as the CLI and the web UI. ``execute_method`` runs a method
marked with ``@component_action`` (an allow-list) on the component's worker, between steps;
``set_param`` changes validated config fields (``ComponentRuntime.set_params``). Both honour the caller's
deadline.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ..declarations.action_schema import bind_call
from ..errors import ComponentError, ConfigError
from ..guardrails import admit_call, with_caller
from ..transport.requests import check_timeout

if TYPE_CHECKING:
    from .hooks import ComponentHooks

__all__ = ["EXECUTE_METHOD_KEYS", "SERVICE_NAMES", "ComponentServices"]

#: The services of every component, each served on ``<component name>/<service>``.
SERVICE_NAMES = ("execute_method", "set_param", "describe", "approvals")

#: The keys of an ``execute_method`` request: ``{"method": name, "args": [...], "kwargs": {...}, "timeout": s,
#: "caller": who (for the audit log: "cli", "ui", "mcp"...), "call_id": an approval id of the caller's,
#: "approval_timeout": the longest the caller lets an approval wait (within ``timeout``)}``
#: (only ``method`` is required; ``timeout`` defaults to 30 s).
EXECUTE_METHOD_KEYS = ("method", "args", "kwargs", "timeout", "caller", "call_id", "approval_timeout")

#: Results sent back as they are; anything else is sent as its repr.
_PLAIN_RESULT = (str, int, float, bool, type(None), list, dict)


class ComponentServices:
    """The handlers of one component's services (each takes a JSON-like request, returns a reply)."""

    def __init__(self, component: ComponentHooks, run_on_worker: Callable[[Callable[[], Any], float], Any],
                 set_params: Callable[[dict[str, Any]], None]) -> None:
        self._component = component
        self._run_on_worker = run_on_worker
        self._set_params = set_params

    def handler(self, service: str) -> Any:
        """The handler of ``service`` (one of :data:`SERVICE_NAMES`)."""
        return {"execute_method": self.execute_method, "set_param": self.set_param,
                "describe": self.describe, "approvals": self.approvals}[service]

    def approvals(self, request: dict[str, Any]) -> dict[str, Any]:
        """The calls of this component's process waiting for a person: ``{"op": "list"}``, or
        ``{"op": "decide", "id": ..., "approve": bool, "by": who}``."""
        from ..guardrails import approvals  # noqa: PLC0415

        broker = approvals()
        op = request.get("op", "list") if isinstance(request, dict) else None
        if op == "list":
            return {"pending": broker.pending()}
        if op == "decide" and isinstance(request.get("id"), str) and isinstance(request.get("approve"), bool):
            by = request.get("by", "")
            return {"decided": broker.decide(request["id"], request["approve"], str(by)[:200])}
        raise ConfigError("approvals needs {'op': 'list'} or {'op': 'decide', 'id': str, 'approve': bool, 'by': str}")

    def describe(self, request: dict[str, Any]) -> dict[str, Any]:
        """What the component is (see :meth:`Component.component_description`)."""
        # Answered where the request is served (its lane, or the caller's thread), not on the
        # worker: a component busy with a long step can still say what it is (the fields read are
        # each updated atomically).
        return self._component.component_description()

    def execute_method(self, request: dict[str, Any]) -> dict[str, Any]:
        """Run the ``@component_action`` named ``request["method"]`` with ``args`` / ``kwargs``, on the worker.

        The request is ``{"method": name, "args": [...], "kwargs": {...}, "timeout": seconds}``
        (:data:`EXECUTE_METHOD_KEYS`; only ``method`` is required). Another key, or no ``method``,
        is refused with a message naming the expected keys (a misspelt ``"name"`` would otherwise
        read as "no action None").
        """
        component = self._component
        expected = ", ".join(repr(k) for k in EXECUTE_METHOD_KEYS)
        if not isinstance(request, dict):
            raise ConfigError(f"execute_method on {component.component_name!r} needs a mapping with the keys "
                              f"{expected}, got {type(request).__name__}")
        unknown = sorted(str(k) for k in request if k not in EXECUTE_METHOD_KEYS)
        if unknown or "method" not in request:
            what = f"unknown key(s) {unknown}" if unknown else "no 'method' key"
            raise ConfigError(f"execute_method on {component.component_name!r}: {what}; expected keys {expected} "
                              f"(only 'method' is required), e.g. {{'method': 'set_word', 'args': ['hello']}}")
        method_name = request.get("method")
        actions = component.available_actions()
        if method_name not in actions:
            raise ComponentError(f"component {component.component_name!r} has no action {method_name!r}; "
                                 f"available: {sorted(actions)}")
        args = request.get("args", [])
        kwargs = request.get("kwargs", {})
        if not isinstance(args, list) or not isinstance(kwargs, dict):
            raise ConfigError("execute_method needs 'args' as a list and 'kwargs' as a mapping")
        method = getattr(component, str(method_name))
        timeout = check_timeout(request.get("timeout", 30.0),
                                f"component {component.component_name!r}: execute_method")
        # One JSON object of parameter names is the arguments by name (agentsctl call talker set_word '{"word": ..}').
        args, kwargs = bind_call(method, args, kwargs, f"component {component.component_name!r}: action "
                                                       f"{method_name!r}")
        caller = request.get("caller", "remote")
        call_id = request.get("call_id")
        if not isinstance(caller, str) or (call_id is not None and not isinstance(call_id, str)):
            raise ConfigError("execute_method: 'caller' and 'call_id' must be strings")
        # Guardrails that wait (approval) or count (rate) are settled here, on the request's thread,
        # within its deadline; the admission carries the caller (and that) to the call on the worker.
        wait = request.get("approval_timeout", timeout)
        if isinstance(wait, bool) or not isinstance(wait, int | float) or not 0 <= wait <= timeout:
            raise ConfigError(f"execute_method: 'approval_timeout' must be seconds within the timeout ({timeout:g})")
        with with_caller(caller[:100], call_id[:64] if call_id else None):
            admission = admit_call(method, component, args, kwargs, float(wait))
        result = self._run_on_worker(lambda: admission.run(method, *args, **kwargs), timeout)
        return {"result": result if isinstance(result, _PLAIN_RESULT) else repr(result)}

    def set_param(self, request: dict[str, Any]) -> dict[str, Any]:
        """Change config fields: ``{"name": ..., "value": ...}`` or ``{"params": {...}}``."""
        params = request.get("params")
        if params is None and "name" in request:
            params = {request["name"]: request.get("value")}
        if not isinstance(params, dict) or not params:
            raise ConfigError("set_param needs {'name': ..., 'value': ...} or {'params': {...}}")
        self._set_params(params)
        return {"ok": True, "params": sorted(params)}
