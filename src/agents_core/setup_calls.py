"""The setup calls made on a component after its construction, recorded for its own process.

With ``add_pkg(multiprocessing=True)`` a component's process rebuilds it from its constructor's
arguments (see :mod:`agents_core.launch.spec`). What the recipe did to it afterwards has to
reach that process as well: the methods marked :func:`setup_method` (``register_tool``,
``set_topic_prompt``, ``add_publisher_preprocessor``, ...) record each call that succeeds on a
constructed component that is not running yet, and the component process replays the calls, in
order, once it has built the component.

Not recorded: calls made while a constructor runs (the process's constructor makes them again),
calls made from inside another recorded call (replaying the outer one makes them), and calls
made once the component is bound to a transport (they happen in the process that runs it).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, TypeVar

import attrs

__all__ = ["SETUP_MARK", "SetupCall", "constructor", "recorded_setup_calls", "setup_method", "start_recording"]

#: The attribute marking a method whose calls are recorded (its value: True).
SETUP_MARK = "_agents_setup_method"
_RECORDER = "_agents_setup_recorder"

F = TypeVar("F", bound=Callable[..., Any])


@attrs.frozen
class SetupCall:
    """One recorded call: ``method(*args, **kwargs)`` on the component."""

    method: str
    args: tuple[Any, ...]
    kwargs: dict[str, Any]


class _Recorder:
    __slots__ = ("calls", "constructing", "nesting")

    def __init__(self) -> None:
        self.calls: list[SetupCall] = []
        self.constructing = 0
        self.nesting = 0


def start_recording(instance: Any) -> None:
    """Give a new instance its (empty) record; called from ``__new__``."""
    object.__setattr__(instance, _RECORDER, _Recorder())


def recorded_setup_calls(instance: Any) -> list[SetupCall]:
    """The setup calls recorded on ``instance``, oldest first."""
    recorder: _Recorder | None = getattr(instance, _RECORDER, None)
    return list(recorder.calls) if recorder is not None else []


def constructor(init: F) -> F:
    """Mark ``__init__`` as a constructor: setup calls made while it runs are not recorded."""
    @functools.wraps(init)
    def wrapper(self: Any, *args: Any, **kwargs: Any) -> Any:
        recorder: _Recorder | None = getattr(self, _RECORDER, None)
        if recorder is None:
            return init(self, *args, **kwargs)
        recorder.constructing += 1
        try:
            return init(self, *args, **kwargs)
        finally:
            recorder.constructing -= 1

    return wrapper  # type: ignore[return-value]


def _bound(instance: Any) -> bool:
    runtime = getattr(instance, "runtime", None)
    return bool(getattr(runtime, "is_bound", False))


def setup_method(func: F) -> F:
    """Record each successful call of ``func`` made on a constructed, not yet running component."""
    @functools.wraps(func)
    def wrapper(self: Any, *args: Any, **kwargs: Any) -> Any:
        recorder: _Recorder | None = getattr(self, _RECORDER, None)
        if recorder is None or recorder.constructing or recorder.nesting or _bound(self):
            return func(self, *args, **kwargs)
        recorder.nesting += 1
        try:
            result = func(self, *args, **kwargs)
        finally:
            recorder.nesting -= 1
        recorder.calls.append(SetupCall(func.__name__, tuple(args), dict(kwargs)))
        return result

    setattr(wrapper, SETUP_MARK, True)
    return wrapper  # type: ignore[return-value]
