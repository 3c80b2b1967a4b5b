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

The record also holds, under the same rules, what the public attributes were when construction
ended (and what each recorded call changed): an attribute holding another object now was
assigned by the recipe (:func:`recorded_assignments`; frozen when the component is bound, so what
a running component does to itself is not counted). And what the component's *probe* counted
(state no attribute shows, such as its publishers' pre-processors) when its construction ended,
plus what each recorded call added: anything else added since was added past the component's
methods (:func:`expected_state`). So what a component is can be read from it as data
(:class:`~agents_core.launch.recipe.Recipe`), without building it again.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, TypeVar

import attrs

__all__ = ["SETUP_MARK", "SetupCall", "constructor", "expected_state", "freeze_record", "recorded_assignments",
           "recorded_setup_calls", "setup_method", "start_recording"]

#: Counts a component's state that no attribute shows (what :func:`expected_state` compares).
Probe = Callable[[Any], dict[str, int]]

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
    __slots__ = ("baseline", "calls", "constructing", "expected", "frozen", "nesting", "probe")

    def __init__(self, probe: Probe | None) -> None:
        self.calls: list[SetupCall] = []
        self.constructing = 0
        self.nesting = 0
        self.probe = probe
        self.expected: dict[str, int] | None = None
        #: The public attributes as construction (and then each recorded call) left them.
        self.baseline: dict[str, Any] | None = None
        self.frozen: list[str] | None = None


_MISSING = object()


def _public(instance: Any) -> dict[str, Any]:
    return {k: v for k, v in vars(instance).items() if not k.startswith("_")}


def start_recording(instance: Any, probe: Probe | None = None) -> None:
    """Give a new instance its (empty) record; called from ``__new__`` (``probe``: see the module docstring)."""
    object.__setattr__(instance, _RECORDER, _Recorder(probe))


def recorded_assignments(instance: Any) -> list[str]:
    """The public attributes assigned on ``instance`` after its construction (not by a recorded call), in order."""
    recorder: _Recorder | None = getattr(instance, _RECORDER, None)
    if recorder is None or recorder.baseline is None:
        return []
    if recorder.frozen is not None:
        return list(recorder.frozen)
    baseline = recorder.baseline
    return [k for k, v in _public(instance).items() if baseline.get(k, _MISSING) is not v]


def freeze_record(instance: Any) -> None:
    """Keep the assignments as they are now (called when the component is bound to a transport)."""
    recorder: _Recorder | None = getattr(instance, _RECORDER, None)
    if recorder is not None and recorder.frozen is None:
        recorder.frozen = recorded_assignments(instance)


def expected_state(instance: Any) -> dict[str, int] | None:
    """What the probe should count now: at the end of construction plus what recorded calls added (None: no probe)."""
    recorder: _Recorder | None = getattr(instance, _RECORDER, None)
    return dict(recorder.expected) if recorder is not None and recorder.expected is not None else None


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
            result = init(self, *args, **kwargs)
        finally:
            recorder.constructing -= 1
        if not recorder.constructing:
            recorder.baseline = _public(self)
            if recorder.probe is not None:
                recorder.expected = recorder.probe(self)  # what the constructor built
        return result

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
        before = recorder.probe(self) if recorder.probe is not None else None
        attributes = _public(self)
        recorder.nesting += 1
        try:
            result = func(self, *args, **kwargs)
        finally:
            recorder.nesting -= 1
        recorder.calls.append(SetupCall(func.__name__, tuple(args), dict(kwargs)))
        if recorder.baseline is not None:  # what this call set is replayed, not carried as an assignment
            recorder.baseline.update({k: v for k, v in _public(self).items() if attributes.get(k, _MISSING) is not v})
        if before is not None and recorder.expected is not None and recorder.probe is not None:
            after = recorder.probe(self)  # what this call added, replayed in the component's process too
            recorder.expected = {k: recorder.expected.get(k, 0) + after[k] - before.get(k, 0) for k in after}
        return result

    setattr(wrapper, SETUP_MARK, True)
    return wrapper  # type: ignore[return-value]
