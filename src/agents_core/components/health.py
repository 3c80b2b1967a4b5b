"""Health and fallbacks of a component, in one place.

A failed step sets the component's health (``ALGORITHM_FAILURE``, ``COMPONENT_FAILURE``,
``SYSTEM_FAILURE``) and runs the matching fallback (or the ``on_any_fail`` one); when a
fallback has used up its retries, the ``on_giveup`` actions run once. The next good step sets
the health back to ``HEALTHY`` and lets the fallbacks start over. Every health change is
reported at once on the component's presence and ``<name>/status`` topic.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from ..actions import Action, Fallback
from ..errors import TransportError
from ..status import HealthStatus

if TYPE_CHECKING:
    from ..transport.contract import ComponentPresence
    from .lifecycle import LifecycleMachine

__all__ = ["HealthAndFallbacks"]


class HealthAndFallbacks:
    """Mixed into :class:`~agents_core.components.component_base.Component`."""

    _logger: logging.Logger
    _fallbacks: dict[str, Fallback]
    _giveup_actions: list[Action]
    _gave_up: bool
    _health: HealthStatus
    _health_message: str
    _recovering: bool
    _failed_steps: int
    _presence: ComponentPresence | None
    _lifecycle: LifecycleMachine

    def on_fail(self, action: Action | Sequence[Action], max_retries: int | None = None) -> None:
        """Run ``action`` (or each in turn) on any failure without a more specific fallback."""
        self._fallbacks["any"] = Fallback(action, max_retries)

    on_any_fail = on_fail

    def on_component_fail(self, action: Action | Sequence[Action], max_retries: int | None = None) -> None:
        """Run ``action`` when a step fails with a component failure (e.g. the model client is down)."""
        self._fallbacks[HealthStatus.COMPONENT_FAILURE.name] = Fallback(action, max_retries)

    def on_algorithm_fail(self, action: Action | Sequence[Action], max_retries: int | None = None) -> None:
        """Run ``action`` when a step raises :class:`~agents_core.errors.AlgorithmFailure`."""
        self._fallbacks[HealthStatus.ALGORITHM_FAILURE.name] = Fallback(action, max_retries)

    def on_system_fail(self, action: Action | Sequence[Action], max_retries: int | None = None) -> None:
        """Run ``action`` when the transport fails under a step."""
        self._fallbacks[HealthStatus.SYSTEM_FAILURE.name] = Fallback(action, max_retries)

    def on_giveup(self, action: Action | Sequence[Action]) -> None:
        """Run ``action`` once when a fallback has used up all its retries."""
        self._giveup_actions = [action] if isinstance(action, Action) else list(action)

    def _step_failed(self, status: HealthStatus, exc: Exception) -> None:
        self._failed_steps += 1
        self._recovering = True
        self._logger.error("step failed (%s): %s: %s", status.name, type(exc).__name__, exc,
                           exc_info=self._logger.isEnabledFor(logging.DEBUG))
        self._set_health(status, f"{type(exc).__name__}: {exc}")
        fallback = self._fallbacks.get(status.name) or self._fallbacks.get("any")
        if fallback is None:
            return
        action = fallback.next_action()
        if action is None:
            if not self._gave_up:
                self._gave_up = True
                self._logger.error("fallbacks exhausted; giving up")
                for giveup in self._giveup_actions:
                    self._run_action(giveup, {})
            return
        self._logger.info("running fallback %s", action.name)
        self._run_action(action, {})

    def _run_action(self, action: Action, values: Mapping[str, Any]) -> Any:
        try:
            return action(values)
        except Exception:
            self._logger.exception("action %s failed", action.name)
            return None

    def _set_health(self, status: HealthStatus, message: str) -> None:
        if status != HealthStatus.HEALTHY:
            self._recovering = True
        changed = status != self._health
        self._health = status
        self._health_message = message
        if changed:
            self._report_status()

    def _report_status(self) -> None:
        presence = self._presence
        if presence is None:
            return
        try:
            presence.update(self._lifecycle.state, self._health, self._health_message)
        except TransportError as exc:
            self._logger.debug("status not published: %s", exc)

