"""``ComponentRuntime``: the one door between a component and whatever runs it (a Launcher, a test).

A component's runtime pieces (its transport, serial worker, presence and services) are
private to it; what a launcher needs goes through ``component.runtime``:

- :meth:`ComponentRuntime.bind`: attach to a transport (presence with the status topic, the
  ``execute_method`` / ``set_param`` / ``describe`` services, the serial worker);
- :meth:`ComponentRuntime.submit_action`: run an event's action on the component's worker,
  between steps;
- :meth:`ComponentRuntime.hurry`: stop waiting for a running step (a second Ctrl-C);
- :meth:`ComponentRuntime.open_action_server` / :meth:`ComponentRuntime.close_action_server`:
  an ACTION_SERVER component whose class sets ``_action_type`` serves goals on
  ``component.action_name`` while active (execute: ``main_action_callback``, accept:
  ``_accept_goal``); each goal runs on a thread of its own, never on the step worker.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future
from typing import TYPE_CHECKING, Any

from ..errors import ComponentError, WiringError
from .run_type import ComponentRunType
from .worker import StepWorker

if TYPE_CHECKING:
    from ..transport.contract import Transport
    from .component_base import Component

__all__ = ["ComponentRuntime"]


class ComponentRuntime:
    """What runs ``component`` (see the module docstring)."""

    def __init__(self, component: Component) -> None:
        self._component = component

    @property
    def is_bound(self) -> bool:
        """Whether the component is attached to a transport."""
        return self._component._transport is not None

    def bind(self, transport: Transport) -> None:
        """Attach to ``transport``: declare the presence (and status topic), the services, start the worker."""
        c = self._component
        if c._transport is not None:
            raise ComponentError(f"component {c.component_name!r} is already launched")
        if c.run_type == ComponentRunType.ACTION_SERVER and not transport.capabilities.actions:
            raise WiringError(f"component {c.component_name!r} runs as an action server, but the "
                              f"{transport.name!r} transport has no long-running goals (actions)")
        c._transport = transport
        c._worker = StepWorker(c.component_name, c.config.execution_queue_depth, c.config.queue_full_policy)
        c._presence = transport.declare_component(c.component_name, on_transition=self._external_transition,
                                                  pending=lambda: c.worker_statistics().pending)
        for service, handler in (("execute_method", c._serve_execute_method), ("set_param", c._serve_set_param),
                                 ("describe", c._serve_describe)):
            c._services.append(transport.create_service(f"{c.component_name}/{service}", handler,
                                                        owner=c.component_name))
        c._report_status()

    def submit_action(self, func: Callable[[], Any]) -> Future[Any]:
        """Run ``func`` on the component's worker, ahead of pending steps; ComponentError if not bound."""
        worker = self._component._worker
        if worker is None:
            raise ComponentError(f"component {self._component.component_name!r} is not launched")
        return worker.submit_control(func)

    def hurry(self) -> None:
        """Stop waiting for a running step in deactivate and shutdown."""
        self._component.hurry_shutdown()

    def open_action_server(self) -> None:
        """Serve the component's goals (at activate), if it is an action server with an ``_action_type``."""
        c = self._component
        action_type = getattr(c, "_action_type", None)
        if c.run_type != ComponentRunType.ACTION_SERVER or action_type is None or c._action_server is not None:
            return
        c._action_server = c.transport.create_action_server(c.action_name, action_type, c.main_action_callback,
                                                            owner=c.component_name, accept=c._accept_goal)

    def close_action_server(self) -> None:
        """Stop serving goals (at deactivate): goals still running end ABORTED with the reason."""
        c = self._component
        server, c._action_server = c._action_server, None
        if server is not None:
            server.close()

    def _external_transition(self, transition: str) -> bool:
        """Run a transition asked from outside (lifecycle service, queryable); never raises."""
        c = self._component
        method = {"configure": c.configure, "activate": c.activate, "deactivate": c.deactivate,
                  "cleanup": c.cleanup, "shutdown": c.shutdown}.get(transition)
        if method is None:
            c.get_logger().warning("unknown lifecycle transition %r requested", transition)
            return False
        try:
            method()
        except Exception as exc:
            c.get_logger().warning("transition %r requested from outside failed: %s", transition, exc)
            return False
        return True
