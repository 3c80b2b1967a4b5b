"""Whether telemetry is on in this process, read by the hot paths with one attribute lookup.

:data:`hooks` is None while telemetry is off (the default): the step, receive, publish and model
paths check it and do nothing more. While on, the per-message spans (receive, step, publish) are
a begin call and an end call each (no context-manager object); the rarer ones are context
managers. :func:`agents_core.telemetry.configure` sets it to the OpenTelemetry hooks
(:mod:`agents_core.telemetry.otel`). This module imports nothing from OpenTelemetry; it
names the hooks' methods as a :class:`Hooks` protocol for the type checker.

:data:`runtimes` holds every bound component runtime of the process (weakly), so that metrics
and ``agentsctl top`` figures can be read from them when asked, at no cost per message.
"""

from __future__ import annotations

import weakref
from collections.abc import Iterator, Mapping
from contextlib import AbstractContextManager
from typing import Any, Protocol

__all__ = ["Hooks", "hooks", "live_runtimes", "runtimes"]


class Hooks(Protocol):
    """What the instrumented code calls while telemetry is on (see :mod:`agents_core.telemetry.otel`)."""

    def enter_remote(self, traceparent: str | None) -> object:
        """Make the context of a received ``traceparent`` current (none: outside any trace); a token for
        :meth:`leave`."""
        ...

    def leave(self, token: object) -> None:
        """Undo :meth:`enter_remote`."""
        ...

    def receive(self, topic: str) -> object:
        """Open the span of one value received on ``topic``, current until :meth:`end` (the value handed on
        meanwhile)."""
        ...

    def end(self, span: object, error: BaseException | None = None) -> None:
        """End a span :meth:`receive` or :meth:`publish` opened (``error``: what it failed with)."""
        ...

    def capture(self) -> object:
        """The current trace context, to carry to another thread."""
        ...

    def step(self, component: str, context: object) -> object:
        """Open the span of one execution step of ``component``, a child of ``context``; ended by
        :meth:`step_end`."""
        ...

    def step_end(self, token: object) -> None:
        """End what :meth:`step` opened (its duration goes to the step histogram)."""
        ...

    def publish(self, topic: str) -> object:
        """Open the span of one value published on ``topic``, current until :meth:`end`."""
        ...

    def traceparent(self) -> str | None:
        """The W3C ``traceparent`` of the current span (None when there is none)."""
        ...

    def model_call(self, model: str, client: str) -> AbstractContextManager[Any]:
        """A span for one model call; its ``record(result)`` adds tokens and wraps a stream."""
        ...

    def call(self, kind: str, name: str, attributes: Mapping[str, Any] | None = None) -> AbstractContextManager[Any]:
        """A span for one tool call, action or goal (``kind``: "tool", "action", "goal")."""
        ...


#: The hooks while telemetry is on in this process; None while it is off.
hooks: Hooks | None = None

#: The bound component runtimes of this process (see the module docstring).
runtimes: weakref.WeakSet[Any] = weakref.WeakSet()


def live_runtimes() -> Iterator[Any]:
    """The bound runtimes, as a list copied now (the set may change meanwhile)."""
    return iter(list(runtimes))
