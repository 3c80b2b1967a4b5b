"""The lifecycle state machine of a component, on its own.

unconfigured -> inactive (configure) -> active (activate) -> inactive (deactivate) ->
unconfigured (cleanup); any -> finalized (shutdown); a transition whose body raises leaves the
component in the error state. The allowed moves are the table in :mod:`agents_core.status`.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

from ..errors import ConfigError, LifecycleError
from ..status import TRANSITIONS, LifecycleState

__all__ = ["LifecycleMachine"]


class LifecycleMachine:
    """Runs transitions one at a time and keeps the state.

    :param component: the component's name, for errors.
    :param on_failed: told ``(transition, exception)`` when a body raised (the state is then error).
    :param on_done: told ``(transition, new state)`` after a transition succeeded.
    """

    def __init__(self, component: str, *, on_failed: Callable[[str, Exception], None],
                 on_done: Callable[[str, LifecycleState], None]) -> None:
        self.component = component
        #: Held during a transition; re-entrant, so a transition may run another (shutdown deactivates).
        self.lock = threading.RLock()
        self.state = LifecycleState.UNCONFIGURED
        self._on_failed = on_failed
        self._on_done = on_done

    def run(self, name: str, body: Callable[[], None]) -> None:
        """Run transition ``name`` with ``body``; LifecycleError when not allowed from the current state."""
        with self.lock:
            allowed_from, target = TRANSITIONS[name]
            if self.state not in allowed_from:
                raise LifecycleError(f"component {self.component!r}: cannot {name} from state {self.state.value!r}")
            try:
                body()
            except Exception as exc:
                self.state = LifecycleState.ERROR
                self._on_failed(name, exc)
                if isinstance(exc, LifecycleError | ConfigError):
                    raise
                raise LifecycleError(f"component {self.component!r}: {name} failed: {exc}") from exc
            self.state = target
            self._on_done(name, target)
