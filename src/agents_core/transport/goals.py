"""Long-running goals: action types, the server's goal handle and the client's goal.

A *goal* is a request that runs for a while: a client sends it (with a goal id), the server
accepts or rejects it, streams *feedback* while it runs, and ends it with a *result* and a
terminal status; the client may ask to *cancel* it meanwhile. This module holds what users see
of that, the same on every transport:

- :class:`GoalStatus`: the numbers of ``action_msgs/msg/GoalStatus``, plus ``REJECTED`` for a
  goal the server did not accept (a client-side outcome that never travels);
- :class:`ActionType` and :data:`ACTION_TYPES`: action definitions by name, each with the field
  specs of its goal, result and feedback. Goals, results and feedback are plain dicts checked
  against them (:meth:`ActionType.validate`): an unknown field or a value of the wrong kind is a
  :class:`~agents_core.errors.TypeValidationError` naming the action, the part and the field;
  missing fields get their defaults. ``VisionLanguageAction`` is built in;
- :class:`GoalHandle`: what a server's execute callback gets;
- :class:`GoalClient`: what ``transport.send_goal`` returns.

The bookkeeping (goal ids, threads per goal, status changes, the closed state) is in
:mod:`agents_core.transport.goal_serving`, once for every driver.
"""

from __future__ import annotations

import contextlib
import enum
import math
import threading
from collections.abc import Callable, Iterator, Mapping
from concurrent.futures import Future
from typing import Any

from attrs import define, field

from ..errors import ComponentError, ConfigError, RequestTimeoutError, TypeValidationError
from ..support.registry import Registry
from .goal_threads import ReusedThreads

__all__ = [
    "ACTION_TYPES",
    "ActionType",
    "FieldSpec",
    "GoalClient",
    "GoalHandle",
    "GoalStatus",
    "action_type",
    "in_inline_feedback",
    "refuse_in_inline_feedback",
    "register_action_type",
]

#: Set on a thread while it runs the feedback callback of a goal sent with ``feedback_inline=True``.
_INLINE = threading.local()
#: The threads that run :meth:`GoalClient.cancel_async`'s requests.
_CANCEL_THREADS = ReusedThreads("goal-cancel-idle")


@contextlib.contextmanager
def inline_feedback() -> Iterator[None]:
    """Mark this thread as running an inline feedback callback for the ``with`` block (nests)."""
    _INLINE.depth = getattr(_INLINE, "depth", 0) + 1
    try:
        yield
    finally:
        _INLINE.depth -= 1


def in_inline_feedback() -> bool:
    """Whether this thread is running the feedback callback of a goal sent with ``feedback_inline=True``."""
    return getattr(_INLINE, "depth", 0) > 0


def refuse_in_inline_feedback(call: str) -> None:
    """Raise :class:`~agents_core.errors.ComponentError` when ``call``, which waits for an answer, is made
    from an inline feedback callback: the callback holds the transport's thread, the one that brings
    the answer in (on Zenoh the call would wait its whole timeout, then fail)."""
    if in_inline_feedback():
        raise ComponentError(
            f"{call} waits for an answer, so it cannot be called from a feedback callback of a goal sent with "
            "feedback_inline=True: that callback runs on the transport's own thread, which has to bring the "
            "answer in. Cancel from there with goal.cancel_async() (do not wait on its Future there), or send "
            "the goal without feedback_inline (its callback then runs on a thread of the goal's own), or hand "
            "the call to a thread of yours.")


class GoalStatus(enum.IntEnum):
    """A goal's status; 0-6 are the numbers of ``action_msgs/msg/GoalStatus``."""

    UNKNOWN = 0
    ACCEPTED = 1
    EXECUTING = 2
    CANCELING = 3
    SUCCEEDED = 4
    CANCELED = 5
    ABORTED = 6
    #: The server did not accept the goal (client side only; never sent on the wire).
    REJECTED = 7

    @property
    def is_terminal(self) -> bool:
        """Whether the goal has ended (succeeded, canceled, aborted or rejected)."""
        return self in _TERMINAL


_TERMINAL = frozenset({GoalStatus.SUCCEEDED, GoalStatus.CANCELED, GoalStatus.ABORTED, GoalStatus.REJECTED})

_UINT32_MAX = 2**32 - 1
#: The field kinds a goal, result or feedback may have.
_KINDS = ("str", "bool", "int", "float", "list[float]", "list[int]", "list[str]")
#: Longest list accepted in a field (a bound on what a peer can make us allocate and copy).
MAX_LIST_LENGTH = 1_000_000
#: Longest string accepted in a field.
MAX_STRING_LENGTH = 1_000_000


@define(frozen=True)
class FieldSpec:
    """One field of a goal, result or feedback: its kind, default and (for ints) bounds.

    :param kind: one of ``"str"``, ``"bool"``, ``"int"``, ``"float"``, ``"list[float]"``,
        ``"list[int]"``, ``"list[str]"``.
    """

    kind: str = field()
    default: Any = None
    minimum: int | None = None
    maximum: int | None = None

    @kind.validator
    def _check_kind(self, _attribute: Any, value: str) -> None:
        if value not in _KINDS:
            raise ConfigError(f"unknown field kind {value!r}; use one of {list(_KINDS)}")

    def default_value(self) -> Any:
        """A fresh default (lists are copied)."""
        if self.default is not None:
            return list(self.default) if isinstance(self.default, list) else self.default
        return {"str": "", "bool": False, "int": 0, "float": 0.0}.get(self.kind, [])

    def check(self, value: Any, where: str) -> Any:
        """``value`` in this field's kind (ints widened to float, numpy arrays to lists), else TypeValidationError."""
        kind = self.kind
        if kind == "str":
            if not isinstance(value, str):
                raise TypeValidationError(f"{where} must be a str, got {type(value).__name__}")
            if len(value) > MAX_STRING_LENGTH:
                raise TypeValidationError(f"{where} is longer than {MAX_STRING_LENGTH} characters")
            return value
        if kind == "bool":
            if not isinstance(value, bool):
                raise TypeValidationError(f"{where} must be a bool, got {type(value).__name__}")
            return value
        if kind.startswith("list["):
            return self._check_list(value, where)
        return _scalar(kind, value, where, self.minimum, self.maximum)

    def _check_list(self, value: Any, where: str) -> list[Any]:
        if hasattr(value, "tolist") and hasattr(value, "ndim"):  # a numpy array, without importing numpy
            if value.ndim != 1:
                raise TypeValidationError(f"{where} must be one-dimensional, got {value.ndim} dimensions")
            value = value.tolist()
        if not isinstance(value, list | tuple):
            raise TypeValidationError(f"{where} must be a list, got {type(value).__name__}")
        if len(value) > MAX_LIST_LENGTH:
            raise TypeValidationError(f"{where} has more than {MAX_LIST_LENGTH} items")
        item = self.kind[5:-1]
        if item == "str":
            return [FieldSpec("str").check(v, f"{where}[{i}]") for i, v in enumerate(value)]
        return [_scalar(item, v, f"{where}[{i}]", None, None) for i, v in enumerate(value)]


def _scalar(kind: str, value: Any, where: str, minimum: int | None, maximum: int | None) -> Any:
    if isinstance(value, bool) or (not isinstance(value, int | float) and not _is_numpy_number(value)):
        raise TypeValidationError(f"{where} must be {'an int' if kind == 'int' else 'a float'}, "
                                  f"got {type(value).__name__}")
    if kind == "float":
        number = float(value)
        if not math.isfinite(number):
            raise TypeValidationError(f"{where} must be a finite float, got {number!r}")
        return number
    if isinstance(value, float) or (_is_numpy_number(value) and not float(value).is_integer()):
        raise TypeValidationError(f"{where} must be an int, got {value!r}")
    number = int(value)
    if (minimum is not None and number < minimum) or (maximum is not None and number > maximum):
        raise TypeValidationError(f"{where} must be in [{minimum}, {maximum}], got {number}")
    return number


def _is_numpy_number(value: Any) -> bool:
    return type(value).__module__ == "numpy" and hasattr(value, "dtype") and getattr(value, "ndim", 1) == 0


def _finite_floats(value: list[Any]) -> bool:
    return all(type(v) is float and math.isfinite(v) for v in value)


#: Per kind: whether a value already is exactly what :meth:`FieldSpec.check` would return (no
#: conversion, within bounds); ints are checked against the field's bounds separately.
_EXACT: dict[str, Callable[[Any], bool]] = {
    "str": lambda v: type(v) is str and len(v) <= MAX_STRING_LENGTH,
    "bool": lambda v: type(v) is bool,
    "int": lambda v: type(v) is int,
    "float": lambda v: type(v) is float and math.isfinite(v),
    "list[float]": lambda v: type(v) is list and len(v) <= MAX_LIST_LENGTH and _finite_floats(v),
    "list[int]": lambda v: type(v) is list and len(v) <= MAX_LIST_LENGTH and all(type(i) is int for i in v),
    "list[str]": lambda v: type(v) is list and len(v) <= MAX_LIST_LENGTH
    and all(type(i) is str and len(i) <= MAX_STRING_LENGTH for i in v),
}


def _exact(specs: dict[str, FieldSpec], value: dict[str, Any]) -> dict[str, Any] | None:
    """``value`` checked when every field already has its exact kind (what feedback on the hot path has);
    None when anything needs converting or is wrong (then the full check converts, or names the error)."""
    checked: dict[str, Any] = {}
    found = 0
    for name, spec in specs.items():
        if name in value:
            v = value[name]
            if not _EXACT[spec.kind](v):
                return None
            if spec.kind == "int" and ((spec.minimum is not None and v < spec.minimum)
                                       or (spec.maximum is not None and v > spec.maximum)):
                return None
            checked[name] = list(v) if type(v) is list else v
            found += 1
        else:
            checked[name] = spec.default_value()
    return checked if found == len(value) else None  # else: an unknown field


def _specs(fields: Mapping[str, FieldSpec | str]) -> dict[str, FieldSpec]:
    return {name: spec if isinstance(spec, FieldSpec) else FieldSpec(spec) for name, spec in fields.items()}


@define(frozen=True, kw_only=True)
class ActionType:
    """A long-running goal's definition: the fields of its goal, result and feedback.

    :param name: the registry name (``"VisionLanguageAction"``).
    :param goal: field name -> :class:`FieldSpec` (or just its kind, with the kind's default).
    :param result: as ``goal``; a ``message`` str field receives the reason of an abort.
    :param feedback: as ``goal``.
    :param ros_type: the ROS 2 action type (``"agents_interfaces/action/VisionLanguageAction"``).
    """

    name: str
    goal: dict[str, FieldSpec] = field(converter=_specs)
    result: dict[str, FieldSpec] = field(converter=_specs)
    feedback: dict[str, FieldSpec] = field(converter=_specs)
    ros_type: str = ""

    def validate(self, part: str, value: Any) -> dict[str, Any]:
        """``value`` (a dict) checked against ``part`` ("goal", "result" or "feedback"), defaults filled in."""
        specs: dict[str, FieldSpec] = getattr(self, part)
        if type(value) is dict:
            checked = _exact(specs, value)
            if checked is not None:
                return checked
        where = f"{self.name} {part}"
        if not isinstance(value, Mapping):
            raise TypeValidationError(f"{where} must be a dict, got {type(value).__name__}")
        unknown = [k for k in value if k not in specs]
        if unknown:
            raise TypeValidationError(f"{where} has unknown field(s) {sorted(map(str, unknown))}; "
                                      f"its fields are {sorted(specs)}")
        return {name: spec.check(value[name], f"{where} field {name!r}") if name in value else spec.default_value()
                for name, spec in specs.items()}

    def defaults(self, part: str) -> dict[str, Any]:
        """Every field of ``part`` at its default."""
        return {name: spec.default_value() for name, spec in getattr(self, part).items()}


#: Action types by name.
ACTION_TYPES: Registry[ActionType] = Registry(
    "action type", hint="register it with agents_core.transport.goals.register_action_type(ActionType(...))")


def register_action_type(definition: ActionType, *, replace: bool = False) -> ActionType:
    """Make ``definition`` usable by name in ``create_action_server`` / ``send_goal``."""
    return ACTION_TYPES.register(definition.name, definition, replace=replace)


def action_type(name: str | ActionType) -> ActionType:
    """The action type registered as ``name`` (an :class:`ActionType` is returned as is)."""
    if isinstance(name, ActionType):
        return name
    return ACTION_TYPES.get(name)


_UINT32 = {"minimum": 0, "maximum": _UINT32_MAX}

register_action_type(ActionType(
    name="VisionLanguageAction",
    goal={"task": FieldSpec("str"), "max_steps": FieldSpec("int", **_UINT32)},
    result={"success": FieldSpec("bool"), "message": FieldSpec("str"), "steps": FieldSpec("int", **_UINT32)},
    feedback={"step": FieldSpec("int", **_UINT32), "action": FieldSpec("list[float]"), "status": FieldSpec("str")},
    ros_type="agents_interfaces/action/VisionLanguageAction",
))


class GoalHandle:
    """One accepted goal as the server's execute callback sees it.

    The callback runs on a thread of the goal's own. It reads :attr:`goal`, sends
    :meth:`publish_feedback`, watches :attr:`cancel_requested` (or sleeps in
    :meth:`wait_for_cancel`), and returns the result dict. It may set the outcome with
    :meth:`succeed`, :meth:`abort` or :meth:`canceled` before returning; if it does not, the
    goal ends canceled when a cancel was requested, else succeeded. If it raises, the goal is
    aborted with the exception's text in the result's ``message`` field (when the type has one).
    """

    def __init__(self, goal_id: str, goal: dict[str, Any], definition: ActionType,
                 send_feedback: Callable[[GoalHandle, dict[str, Any]], None],
                 on_cancel_requested: Callable[[GoalHandle], None]) -> None:
        self.goal_id = goal_id
        self.goal = goal
        self.action_type = definition
        self._send_feedback = send_feedback
        self._on_cancel_requested = on_cancel_requested
        self._cancel = threading.Event()
        self._lock = threading.Lock()
        self._outcome: GoalStatus | None = None
        self._ended = False
        self._abort_reason = ""
        self.feedback_sent = 0

    @property
    def cancel_requested(self) -> bool:
        """Whether a client asked to cancel this goal (or the server preempted it, or is closing)."""
        return self._cancel.is_set()

    @property
    def outcome(self) -> GoalStatus | None:
        """The terminal status set with succeed / abort / canceled, if any."""
        return self._outcome

    def wait_for_cancel(self, timeout: float) -> bool:
        """Sleep up to ``timeout`` seconds, waking early on a cancel request; whether one came."""
        return self._cancel.wait(max(0.0, timeout))

    def request_cancel(self) -> None:
        """Ask this goal to stop (server-side preemption); the client sees CANCELING."""
        with self._lock:
            if self._cancel.is_set() or self._ended:
                return
            self._cancel.set()
        self._on_cancel_requested(self)

    def publish_feedback(self, feedback: Mapping[str, Any]) -> None:
        """Send ``feedback`` (checked against the type's feedback fields) to the client.

        Raises :class:`~agents_core.errors.TypeValidationError` for a bad field and
        :class:`~agents_core.errors.ComponentError` once the goal has ended.
        """
        if self._ended:
            raise ComponentError(f"goal {self.goal_id} of {self.action_type.name} has ended; feedback not sent")
        checked = self.action_type.validate("feedback", feedback)
        self._send_feedback(self, checked)
        self.feedback_sent += 1

    def succeed(self) -> None:
        """End the goal as succeeded (with the result the callback returns)."""
        self._set_outcome(GoalStatus.SUCCEEDED)

    def abort(self, reason: str = "") -> None:
        """End the goal as aborted; ``reason`` fills the result's ``message`` when the callback leaves it empty."""
        self._abort_reason = reason
        self._set_outcome(GoalStatus.ABORTED)

    def canceled(self) -> None:
        """End the goal as canceled (normally after :attr:`cancel_requested`)."""
        self._set_outcome(GoalStatus.CANCELED)

    def _set_outcome(self, status: GoalStatus) -> None:
        if self._ended:
            raise ComponentError(f"goal {self.goal_id} of {self.action_type.name} has already ended")
        self._outcome = status

    def _end(self) -> None:
        with self._lock:
            self._ended = True

    def __repr__(self) -> str:
        return f"<GoalHandle {self.action_type.name} {self.goal_id} cancel_requested={self.cancel_requested}>"


class GoalClient:
    """A goal sent with ``transport.send_goal``: its id, acceptance, status, result and cancel.

    Feedback reaches the ``feedback`` callback given to ``send_goal`` on a thread of this goal's
    own, never on the middleware's (unless it was sent with ``feedback_inline=True``: then
    :meth:`result` and :meth:`cancel` refuse to wait from that callback, :meth:`cancel_async` does not wait).
    """

    def __init__(self, goal_id: str, action_name: str, definition: ActionType) -> None:
        self.goal_id = goal_id
        self.action_name = action_name
        self.action_type = definition
        self.accepted = False
        self._status = GoalStatus.UNKNOWN
        self._result: dict[str, Any] | None = None
        self._done = threading.Event()
        self._lock = threading.Lock()
        self._cancel: Callable[[float], bool] | None = None
        self._on_done: list[Callable[[], None]] = []
        #: Feedback messages received / dropped (a slow callback) / not decodable.
        self.feedback_received = 0
        self.feedback_dropped = 0
        self.feedback_errors = 0

    @property
    def status(self) -> GoalStatus:
        """The last status known here."""
        return self._status

    def _accepted(self, cancel: Callable[[float], bool]) -> None:
        """The server accepted the goal; ``cancel(timeout)`` asks it to cancel (called by the sender)."""
        self.accepted = True
        self._cancel = cancel
        self._set_status(GoalStatus.ACCEPTED)

    @property
    def done(self) -> bool:
        """Whether the result (or a terminal status) has arrived."""
        return self._done.is_set()

    def result(self, timeout: float) -> tuple[GoalStatus, dict[str, Any]]:
        """Wait for the terminal status and the result dict.

        Raises :class:`~agents_core.errors.RequestTimeoutError` if it has not come within ``timeout``,
        and ComponentError when it would wait (``timeout > 0``) from an inline feedback callback
        (see :func:`refuse_in_inline_feedback`).
        """
        if timeout > 0:
            refuse_in_inline_feedback("goal.result()")
        if not self._done.wait(max(0.0, timeout)):
            raise RequestTimeoutError(f"goal {self.goal_id} on {self.action_name!r} has no result within "
                                      f"{timeout:g} s (status {self._status.name})")
        assert self._result is not None
        return self._status, dict(self._result)

    def cancel(self, timeout: float = 5.0) -> bool:
        """Ask the server to cancel the goal; whether it agreed (False for a goal that has ended).

        It waits for the server's answer: from a ``feedback_inline=True`` callback it raises
        ComponentError, use :meth:`cancel_async` there.
        """
        refuse_in_inline_feedback("goal.cancel()")
        if self._done.is_set() or self._cancel is None:
            return False
        return self._cancel(timeout)

    def cancel_async(self, timeout: float = 5.0) -> Future[bool]:
        """Ask the server to cancel the goal without waiting: a Future of what :meth:`cancel` returns.

        The request runs on a thread of its own, so this is how to cancel from a
        ``feedback_inline=True`` callback (which must not wait on the Future: the answer comes in once
        the callback has returned).
        """
        future: Future[bool] = Future()
        if self._done.is_set() or self._cancel is None:
            future.set_result(False)
            return future

        def ask() -> None:
            if not future.set_running_or_notify_cancel():
                return
            try:
                future.set_result(self.cancel(timeout))
            except Exception as exc:
                future.set_exception(exc)

        _CANCEL_THREADS.run(ask, f"goal-cancel:{self.goal_id[:8]}")
        return future

    # -- fed by the core ------------------------------------------------------------------------

    def _set_status(self, status: GoalStatus) -> None:
        with self._lock:
            # Statuses only move forward (ACCEPTED < EXECUTING < CANCELING): a late ACCEPTED
            # from the acceptance reply must not hide the EXECUTING that overtook it.
            if not self._done.is_set() and not status.is_terminal and status > self._status:
                self._status = status

    def _when_done(self, callback: Callable[[], None]) -> None:
        """Call ``callback`` once the goal has ended (at once if it has)."""
        with self._lock:
            if not self._done.is_set():
                self._on_done.append(callback)
                return
        callback()

    def _finish(self, status: GoalStatus, result: dict[str, Any]) -> bool:
        """Record the outcome once; False if it was already recorded."""
        with self._lock:
            if self._done.is_set():
                return False
            self._status = status
            self._result = result
            self._done.set()
            callbacks, self._on_done = self._on_done, []
        for callback in callbacks:
            callback()
        return True

    def __repr__(self) -> str:
        return f"<GoalClient {self.action_name!r} {self.goal_id} {self._status.name}>"
