"""Where a checked plan step goes: an Action, a component's ``execute_method`` service, or a goal.

The same calls work whether the target runs in this process or another one (``multiprocessing=True``):
component actions always travel through the transport's ``<component>/execute_method`` service,
goals through ``transport.send_goal``. An :class:`~agents_core.actions.Action` of a component
running in this process runs on that component's worker; of a component elsewhere, through its
service; a plain function runs here.

Goals a task starts are kept (:attr:`Dispatcher.running`) so the executor can wait for them,
report their progress to the confirmation model, and cancel them when the task stops.
"""

from __future__ import annotations

import json
import threading
from typing import TYPE_CHECKING, Any

from ...transport.goals import GoalClient, GoalStatus
from .peers import as_data
from .tools import Tool

if TYPE_CHECKING:
    from ...transport.contract import Transport

__all__ = ["Dispatcher", "StepFailed"]


class StepFailed(Exception):
    """A dispatched step failed; ``str()`` says why (the executor records it and goes on to confirmation)."""


def _text(value: Any) -> str:
    if isinstance(value, str):
        return value
    try:
        return json.dumps(value, default=str)
    except (TypeError, ValueError):
        return repr(value)


class _RunningGoal:
    def __init__(self, tool: str, component: str, client: GoalClient) -> None:
        self.tool = tool
        self.component = component
        self.client = client
        self.last_feedback: dict[str, Any] | None = None


class Dispatcher:
    """Runs checked steps for one Cortex (see the module docstring)."""

    def __init__(self, transport: Transport, dispatch_timeout: float, goal_accept_timeout: float) -> None:
        self._transport = transport
        self._dispatch_timeout = dispatch_timeout
        self._accept_timeout = goal_accept_timeout
        self._lock = threading.Lock()
        self._running: list[_RunningGoal] = []
        #: Steps dispatched, for statistics and benchmarks.
        self.dispatched = 0

    # -- steps --------------------------------------------------------------------------------------

    def run(self, tool: Tool, arguments: dict[str, Any]) -> str:
        """Dispatch one step; its result as text, or StepFailed with the reason."""
        self.dispatched += 1
        try:
            if tool.kind == "action":
                return self._run_action(tool)
            if tool.kind == "component_action":
                return self._call_component(tool, arguments)
            if tool.kind == "goal":
                return self._send_goal(tool, arguments)
            if tool.kind == "mcp":
                from .mcp_tools import call_mcp_tool  # noqa: PLC0415

                return _text(call_mcp_tool(tool, arguments))
        except StepFailed:
            raise
        except Exception as exc:
            raise StepFailed(f"{tool.name} failed: {type(exc).__name__}: {exc}") from exc
        raise StepFailed(f"{tool.name} is a {tool.kind} tool, which is not a plan step")

    def call_component(self, component: str, method: str, arguments: dict[str, Any]) -> str:
        """Call ``component.method(**arguments)`` through its ``execute_method`` service (research tools too)."""
        reply = self._transport.request(f"{component}/execute_method",
                                        {"method": method, "args": [], "kwargs": arguments,
                                         "timeout": self._dispatch_timeout},
                                        timeout=self._dispatch_timeout + 1.0)
        return _text(reply.get("result"))

    def _call_component(self, tool: Tool, arguments: dict[str, Any]) -> str:
        assert tool.component is not None
        return self.call_component(tool.component, tool.target, arguments)

    def _run_action(self, tool: Tool) -> str:
        # Imported here: the component base imports the whole runtime, which this module does not need.
        from ..component_base import Component  # noqa: PLC0415

        action = tool.action
        owner = action.owner
        if isinstance(owner, Component):
            if owner.runtime.is_bound:
                result = owner.run_on_worker(lambda: action({}), self._dispatch_timeout)
            else:
                # The component runs in another process: this copy of it is not running.
                args, kwargs = action.resolve({})
                reply = self._transport.request(f"{owner.component_name}/execute_method",
                                                {"method": action.name, "args": list(args), "kwargs": kwargs,
                                                 "timeout": self._dispatch_timeout},
                                                timeout=self._dispatch_timeout + 1.0)
                result = reply.get("result")
        else:
            result = action({})
        return f"{tool.name} done" if result is None or result is True else _text(result)

    def _send_goal(self, tool: Tool, arguments: dict[str, Any]) -> str:
        assert tool.component is not None
        running = _RunningGoal(tool.name, tool.component, None)  # type: ignore[arg-type]

        def on_feedback(feedback: dict[str, Any]) -> None:
            running.last_feedback = feedback

        client = self._transport.send_goal(tool.component, tool.target, arguments, feedback=on_feedback,
                                           timeout=self._accept_timeout)
        if not client.accepted or client.status == GoalStatus.REJECTED:
            raise StepFailed(f"{tool.component!r} rejected the goal {arguments}")
        running.client = client
        with self._lock:
            self._running.append(running)
        return f"goal {arguments} accepted by {tool.component!r}; it runs in the background"

    # -- running goals ------------------------------------------------------------------------------

    def running(self) -> list[str]:
        """Components with goals of this task still running."""
        with self._lock:
            return [g.component for g in self._running if not g.client.done]

    def goal_report(self) -> str:
        """The goals of this task, one line each (status, latest feedback or result, marked as data)."""
        with self._lock:
            goals = list(self._running)
        lines = []
        for g in goals:
            if g.client.done:
                status, result = g.client.result(0.0)
                lines.append(f"- {g.tool}: {status.name}, result {as_data(f'{g.tool} result', _text(result))}")
            else:  # what the action server sends is marked as its data, as tool results are
                extra = (f", latest feedback {as_data(f'{g.tool} feedback', _text(g.last_feedback))}"
                         if g.last_feedback else "")
                lines.append(f"- {g.tool}: {g.client.status.name} (running){extra}")
        return "\n".join(lines)

    def cancel_all(self, timeout: float = 5.0) -> list[str]:
        """Cancel every goal of this task still running; the components whose goal agreed to stop."""
        with self._lock:
            goals, self._running = list(self._running), []
        stopped = []
        for g in goals:
            if not g.client.done:
                try:
                    if g.client.cancel(timeout):
                        stopped.append(g.component)
                except Exception:  # a cancel that fails must not keep the others running
                    continue
        return stopped

    def forget(self) -> None:
        """Drop the record of finished goals (a new task starts)."""
        with self._lock:
            self._running = [g for g in self._running if not g.client.done]
