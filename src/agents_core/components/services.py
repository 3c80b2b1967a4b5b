"""The services every component serves, in one place: ``<name>/execute_method``, ``<name>/set_param``
and ``<name>/describe``.

``describe`` answers what the component is (type, run type, state, health, inputs, outputs,
callable actions), for tools such as the CLI and the web UI. ``execute_method`` runs a method
marked with ``@component_action`` (an allow-list) on the component's worker, between steps;
``set_param`` changes validated config fields, live ones at once (see
:meth:`ComponentServices.set_params`). Both honour the caller's deadline.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ..actions import ACTION_MARK
from ..config import BaseComponentConfig, configure_time_fields
from ..errors import ComponentError, ConfigError, RequestTimeoutError
from ..status import LifecycleState
from ..transport.requests import check_timeout, request_deadline
from .worker import PeriodicTimer, StepWorker

if TYPE_CHECKING:
    from ..status import HealthStatus
    from ..topics import Topic
    from .lifecycle import LifecycleMachine
    from .run_type import ComponentRunType

__all__ = ["ComponentServices"]


class ComponentServices:
    """Mixed into :class:`~agents_core.components.component_base.Component`."""

    component_name: str
    config: BaseComponentConfig
    _logger: logging.Logger
    _worker: StepWorker | None
    _status_timer: PeriodicTimer | None
    _lifecycle: LifecycleMachine
    inputs: list[Topic]
    outputs: list[Topic]
    run_type: ComponentRunType
    _health: HealthStatus

    def _report_status(self) -> None:
        """Publish the current state (implemented by the health mixin, which comes first in the MRO)."""
        raise NotImplementedError

    def available_actions(self) -> dict[str, dict[str, Any]]:
        """The methods marked with ``@component_action`` and their OpenAI-style descriptions."""
        found: dict[str, dict[str, Any]] = {}
        for name in dir(type(self)):
            attr = getattr(type(self), name, None)
            description = getattr(attr, ACTION_MARK, None)
            if description is not None:
                found[name] = description
        return found

    def component_description(self) -> dict[str, Any]:
        """What ``<name>/describe`` answers: name, type, run type, state, health, inputs, outputs, actions."""
        return {
            "name": self.component_name,
            "component_type": type(self).__name__,
            "run_type": self.run_type.value,
            "state": self._lifecycle.state.value,
            "health": self._health.name,
            "inputs": [{"name": t.name, "msg_type": t.type_name} for t in self.inputs],
            "outputs": [{"name": t.name, "msg_type": t.type_name} for t in self.outputs],
            "actions": self.available_actions(),
        }

    def _serve_describe(self, request: dict[str, Any]) -> dict[str, Any]:
        # Answered on the request lane, not the worker: a component busy with a long step can
        # still say what it is (the fields read are each updated atomically).
        return self.component_description()

    def _serve_execute_method(self, request: dict[str, Any]) -> dict[str, Any]:
        method_name = request.get("method")
        actions = self.available_actions()
        if method_name not in actions:
            raise ComponentError(f"component {self.component_name!r} has no action {method_name!r}; "
                                 f"available: {sorted(actions)}")
        args = request.get("args", [])
        kwargs = request.get("kwargs", {})
        if not isinstance(args, list) or not isinstance(kwargs, dict):
            raise ConfigError("execute_method needs 'args' as a list and 'kwargs' as a mapping")
        method = getattr(self, str(method_name))
        timeout = check_timeout(request.get("timeout", 30.0), f"component {self.component_name!r}: execute_method")
        result = self.run_on_worker(lambda: method(*args, **kwargs), timeout=timeout)
        return {"result": result if isinstance(result, str | int | float | bool | type(None) | list | dict)
                else repr(result)}

    def _serve_set_param(self, request: dict[str, Any]) -> dict[str, Any]:
        params = request.get("params")
        if params is None and "name" in request:
            params = {request["name"]: request.get("value")}
        if not isinstance(params, dict) or not params:
            raise ConfigError("set_param needs {'name': ..., 'value': ...} or {'params': {...}}")
        self.set_params(**params)
        return {"ok": True, "params": sorted(params)}

    def set_params(self, **params: Any) -> None:
        """Change config fields of a running component, validated, applied at once.

        Live settings (``execution_queue_depth``, ``queue_full_policy``, ``log_level``,
        ``status_rate`` and what the component reads at each step) take effect immediately. Fields
        used only at configure (model files, local model settings, ...) are refused with
        :class:`~agents_core.errors.ConfigError` unless the component is unconfigured. An invalid
        value changes nothing.
        """
        at_configure = sorted(set(params) & configure_time_fields(self.config))
        if at_configure and self._lifecycle.state != LifecycleState.UNCONFIGURED:
            raise ConfigError(f"component {self.component_name!r}: {at_configure} apply at configure only; "
                              "deactivate and clean up the component, set them, then configure it again")
        self.run_on_worker(lambda: self._apply_params(params), timeout=10.0)

    def _apply_params(self, params: dict[str, Any]) -> None:
        self.config.update(**params)
        changed = set(params)
        if "log_level" in changed:
            self._logger.setLevel(self.config.log_level.upper())
        if self._worker is not None and changed & {"execution_queue_depth", "queue_full_policy"}:
            self._worker.set_queue(self.config.execution_queue_depth, self.config.queue_full_policy)
        if "status_rate" in changed and self._status_timer is not None:
            self._status_timer.stop()
            self._status_timer = PeriodicTimer(self.config.status_rate, self._report_status,
                                               f"{self.component_name}:status")

    def run_on_worker(self, func: Callable[[], Any], timeout: float = 30.0) -> Any:
        """Run ``func`` on the component's worker (between steps) and return its result.

        Waits at most ``timeout`` s, less when serving a request whose caller waits less; an
        item whose wait expired before it started is never run (``RequestTimeoutError``).
        """
        if self._worker is None or self._worker.on_worker_thread:
            return func()
        timeout = check_timeout(timeout, f"component {self.component_name!r}: run_on_worker")
        deadline = time.monotonic() + timeout
        caller_deadline = request_deadline()
        if caller_deadline is not None:
            deadline = min(deadline, caller_deadline)
        future = self._worker.submit_control(func, deadline=deadline)
        try:
            return future.result(timeout=max(0.0, deadline - time.monotonic()))
        except TimeoutError:
            if future.cancel():
                raise RequestTimeoutError(f"component {self.component_name!r}: the worker did not get to the "
                                          f"request within {timeout:g} s (busy with a step?)") from None
            if not future.done():
                raise RequestTimeoutError(f"component {self.component_name!r}: the request did not finish within "
                                          f"{timeout:g} s") from None
            raise

