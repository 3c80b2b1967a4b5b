"""A component's health and fallbacks, as one object of its runtime.

A failed step sets the health (``ALGORITHM_FAILURE``, ``COMPONENT_FAILURE``, ``SYSTEM_FAILURE``)
and runs the matching fallback (or the ``on_any_fail`` one); when a fallback has used up its
retries, the ``on_giveup`` actions run once. The next good step sets the health back to
``HEALTHY`` and lets the fallbacks start over. Every health change is reported at once through
the ``report`` callable the runtime gives (the component's presence and ``<name>/status`` topic).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from ..actions import Action, Fallback
from ..errors import ConfigError
from ..status import HealthStatus
from .repeated_failures import RepeatedFailures

__all__ = ["ANY_FAILURE", "Health"]

#: The fallback key of ``on_fail`` / ``on_any_fail``: used when no fallback matches the failure.
ANY_FAILURE = "any"


class Health:
    """The health status of one component and the fallbacks that answer its failures.

    :param logger: the component's logger.
    :param report: publishes the current state and health (called on every change).
    """

    def __init__(self, logger: logging.Logger, report: Callable[[], None]) -> None:
        self._logger = logger
        self._report = report
        self._status = HealthStatus.HEALTHY
        self._message = ""
        self._fallbacks: dict[str, Fallback] = {}
        self._giveup_actions: list[Action] = []
        self._giveup_tries = 1
        self._gave_up = False
        self._failed_steps = 0
        # Set by a failure (or a change away from HEALTHY), cleared by the next good step: the
        # common path of a step checks one flag.
        self._recovering = False
        self._repeats = RepeatedFailures(logger)

    # -- what it is now -----------------------------------------------------------------------

    @property
    def status(self) -> HealthStatus:
        """The current health status."""
        return self._status

    @property
    def message(self) -> str:
        """Why the component is not healthy (empty when it is)."""
        return self._message

    @property
    def failed_steps(self) -> int:
        """How many steps raised (not counting steps overtaken by a deactivate)."""
        return self._failed_steps

    @property
    def fallbacks(self) -> Mapping[str, Fallback]:
        """The fallbacks by failure kind (a ``HealthStatus`` name, or :data:`ANY_FAILURE`)."""
        return dict(self._fallbacks)

    @property
    def giveup_retries(self) -> int:
        """How many times a raising give-up action is tried."""
        return self._giveup_tries

    @property
    def giveup_actions(self) -> list[Action]:
        """The actions run once when a fallback is exhausted."""
        return list(self._giveup_actions)

    # -- configuring it ------------------------------------------------------------------------

    def set_fallback(self, kind: str, action: Action | Sequence[Action] | Fallback,
                     max_retries: int | None = None) -> None:
        """Answer failures of ``kind`` (a ``HealthStatus`` name or :data:`ANY_FAILURE`) with ``action``."""
        self._fallbacks[kind] = action if isinstance(action, Fallback) else Fallback(action, max_retries)

    def set_giveup(self, action: Action | Sequence[Action], max_retries: int | None = None) -> None:
        """Run ``action`` (or each in turn) once when a fallback has used up all its retries.

        ``max_retries`` (upstream's argument): how many times an action that raises is tried
        (default once).
        """
        if max_retries is not None and (isinstance(max_retries, bool) or not isinstance(max_retries, int)
                                        or max_retries < 1):
            raise ConfigError(f"max_retries must be a positive int or None, got {max_retries!r}")
        self._giveup_actions = [action] if isinstance(action, Action) else list(action)
        self._giveup_tries = max_retries or 1

    # -- what happens to it --------------------------------------------------------------------

    def set(self, status: HealthStatus, message: str) -> None:
        """Set the health; a change is reported at once."""
        if status != HealthStatus.HEALTHY:
            self._recovering = True
        changed = status != self._status
        self._status = status
        self._message = message
        if changed:
            self._report()

    def step_failed(self, status: HealthStatus, exc: Exception) -> None:
        """A step raised: set the health and run the matching fallback (or give up)."""
        self._failed_steps += 1
        self.failed(status, exc, "step")

    def mark_failed(self, status: HealthStatus, exc: Exception, during: str) -> None:
        """Something failed ``during`` a transition: set the health and log it (once, then counted), but run no
        fallback: for a failure the fallbacks are not about (a database down, while the model whose client they
        switch works). The next success makes the component healthy again, as after :meth:`failed`."""
        self._recovering = True
        line = f"{during} failed ({status.name}): {type(exc).__name__}: {exc}"
        if self._repeats.should_log((during, status.name, type(exc).__name__, str(exc)), line):  # once, then counted
            self._logger.error("%s", line, exc_info=self._logger.isEnabledFor(logging.DEBUG))
        self.set(status, f"{type(exc).__name__}: {exc}")

    def failed(self, status: HealthStatus, exc: Exception, during: str) -> bool:
        """Something failed ``during`` a step or a transition: set the health, run the matching fallback.

        Returns whether a fallback action ran (False: none matches, or they are used up and the
        ``on_giveup`` actions ran instead).
        """
        self.mark_failed(status, exc, during)
        fallback = self._fallbacks.get(status.name) or self._fallbacks.get(ANY_FAILURE)
        if fallback is None:
            return False
        action = fallback.next_action()
        if action is None:
            if not self._gave_up:
                self._gave_up = True
                self._logger.error("fallbacks exhausted; giving up")
                for giveup in self._giveup_actions:
                    self._run_giveup(giveup)
            return False
        self._logger.info("running fallback %s", action.name)
        self.run_action(action, {})
        return True

    def _run_giveup(self, action: Action) -> None:
        for attempt in range(1, self._giveup_tries + 1):
            try:
                action({})
                return
            except Exception:
                self._logger.exception("give-up action %s failed (try %d of %d)", action.name, attempt,
                                       self._giveup_tries)

    def step_succeeded(self) -> None:
        """A step (or a retried configure) ended well: after failures, healthy again and the
        fallbacks start over."""
        if not self._recovering:
            return
        self._recovering = False
        self._repeats.recovered()
        if self._status != HealthStatus.HEALTHY:
            self.set(HealthStatus.HEALTHY, "")
        for fallback in self._fallbacks.values():
            fallback.reset()
        self._gave_up = False

    def stopped(self) -> None:
        """The component deactivated: how often its last failure repeated is said now, not lost."""
        self._repeats.stopped()

    def run_action(self, action: Action, values: Mapping[str, Any]) -> Any:
        """Run ``action`` with ``values``; a raising action is logged, never propagated."""
        try:
            return action(values)
        except Exception:
            self._logger.exception("action %s failed", action.name)
            return None
