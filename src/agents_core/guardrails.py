"""Guardrails between a decision (a model's, a person's, a script's) and a component's action.

Declared where the action is declared, checked in the action itself, so that every caller meets
them: an MCP client, the Cortex, an LLM's tool call, ``execute_method``, the web UI, the CLI and
plain Python::

    @component_action(limits={"speed": (0.0, 0.5)}, approval=True, rate_limit=(5, 60.0))
    def move(self, speed: float, distance: float = 1.0) -> str: ...

- ``limits``: each named argument must be a real, finite number within ``(low, high)`` (each
  element, for a list of numbers); otherwise the call is refused before the method runs
  (:class:`GuardrailRefused`, naming the argument and the range).
- ``rate_limit``: ``(calls, seconds)``: at most that many calls in any window of that many seconds
  (per component); the rest are refused.
- ``approval``: the call waits until a person approves it (:func:`approvals`: the web UI,
  ``agentsctl approve`` / ``deny``, MCP elicitation), and is refused when denied or when
  ``approval_timeout`` seconds (default 60) pass: it never runs late.

Every guarded or not guarded action call is written to the :func:`audit_log` (time, caller, action,
arguments, decision, outcome), one JSON object a line, when an audit file is configured
(``AGENTS_AUDIT_LOG``, or :func:`configure_audit_log`).

Who is calling is the :data:`current_caller` context value (``"python"`` unless a service set it:
``execute_method`` takes a ``caller`` key, ``"mcp"``, ``"cli"``, ``"ui"``...).
"""

from __future__ import annotations

import contextlib
import contextvars
import inspect
import json
import math
import os
import threading
import time
import uuid
from collections import deque
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from attrs import define, field

from .errors import ComponentError, ConfigError

__all__ = [
    "DEFAULT_APPROVAL_TIMEOUT",
    "ActionGuard",
    "Admission",
    "ApprovalBroker",
    "AuditLog",
    "GuardrailRefused",
    "PendingCall",
    "admit_call",
    "approvals",
    "audit_log",
    "configure_audit_log",
    "current_caller",
    "run_guarded",
    "with_caller",
]

#: Who is calling the action now (set by services for the call they run).
current_caller: contextvars.ContextVar[str] = contextvars.ContextVar("agents_core_caller", default="python")
#: An approval id chosen by the caller (so that an MCP server can decide the pending call it started).
_call_id: contextvars.ContextVar[str | None] = contextvars.ContextVar("agents_core_call_id",
                                                                       default=None)

#: The longest an approval may wait unless an action says otherwise (seconds).
DEFAULT_APPROVAL_TIMEOUT = 60.0
#: Arguments longer than this (as JSON) are cut in audit records and approval requests.
_AUDIT_VALUE_CHARS = 2000


class GuardrailRefused(ComponentError):
    """An action call refused by its guardrails (out of range, too often, not approved): it did not run."""


def _check_limits(value: Any) -> dict[str, tuple[float, float]]:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ConfigError(f"limits must map argument names to (low, high), got {type(value).__name__}")
    checked: dict[str, tuple[float, float]] = {}
    for name, bounds in value.items():
        try:
            low, high = (float(b) for b in bounds)
        except (TypeError, ValueError):
            raise ConfigError(f"limits[{name!r}] must be (low, high) numbers, got {bounds!r}") from None
        if not (math.isfinite(low) and math.isfinite(high)) or low > high:
            raise ConfigError(f"limits[{name!r}] must be finite with low <= high, got {bounds!r}")
        checked[str(name)] = (low, high)
    return checked


def _check_rate(value: Any) -> tuple[int, float] | None:
    if value is None:
        return None
    try:
        calls, seconds = value
        calls, seconds = int(calls), float(seconds)
    except (TypeError, ValueError):
        raise ConfigError(f"rate_limit must be (calls, seconds), got {value!r}") from None
    if calls < 1 or not (math.isfinite(seconds) and seconds > 0):
        raise ConfigError(f"rate_limit must be (calls >= 1, seconds > 0), got {value!r}")
    return calls, seconds


def _check_timeout(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not (0 < float(value) <= 3600):
        raise ConfigError(f"approval_timeout must be seconds in (0, 3600], got {value!r}")
    return float(value)


@define(frozen=True)
class ActionGuard:
    """The guardrails of one action (see the module docs)."""

    limits: dict[str, tuple[float, float]] = field(factory=dict, converter=_check_limits)
    approval: bool = False
    approval_timeout: float = field(default=DEFAULT_APPROVAL_TIMEOUT, converter=_check_timeout)
    rate_limit: tuple[int, float] | None = field(default=None, converter=_check_rate)

    @property
    def active(self) -> bool:
        """Whether there is anything to check."""
        return bool(self.limits) or self.approval or self.rate_limit is not None

    def describe(self) -> dict[str, Any]:
        """The guardrails as JSON (in the action's description, so tools can show them)."""
        out: dict[str, Any] = {}
        if self.limits:
            out["limits"] = {k: list(v) for k, v in self.limits.items()}
        if self.approval:
            out["approval"] = True
            out["approval_timeout"] = self.approval_timeout
        if self.rate_limit is not None:
            out["rate_limit"] = list(self.rate_limit)
        return out

    def check_arguments(self, where: str, arguments: Mapping[str, Any]) -> None:
        """Refuse arguments outside their limits (NaN and infinities included; a bool is not a number)."""
        for name, (low, high) in self.limits.items():
            if name not in arguments:
                continue
            value = arguments[name]
            values = value if isinstance(value, list | tuple) else [value]
            for item in values:
                if isinstance(item, bool) or not isinstance(item, int | float):
                    raise GuardrailRefused(f"{where}: argument {name!r} must be a number in [{low:g}, {high:g}], "
                                           f"got {_short(item)}")
                if not (math.isfinite(float(item)) and low <= float(item) <= high):
                    raise GuardrailRefused(f"{where}: argument {name!r} = {_short(item)} is outside "
                                           f"[{low:g}, {high:g}]; the action did not run")


def _short(value: Any) -> str:
    try:
        text = json.dumps(value, default=repr, allow_nan=True)
    except (TypeError, ValueError, RecursionError):
        text = repr(type(value))
    return text if len(text) <= _AUDIT_VALUE_CHARS else text[:_AUDIT_VALUE_CHARS] + "..."


def _shown(value: Any) -> Any:
    """``value`` as JSON data when it is short and plain; otherwise its (cut) JSON text."""
    text = _short(value)
    try:
        return json.loads(text, parse_constant=str)  # NaN / Infinity shown as text: they are not JSON
    except ValueError:
        return text


class _RateWindow:
    """Call times of one (component, action) in a sliding window."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._times: dict[tuple[int, str], deque[float]] = {}

    def admit(self, key: tuple[int, str], calls: int, seconds: float) -> bool:
        now = time.monotonic()
        with self._lock:
            window = self._times.setdefault(key, deque())
            while window and now - window[0] >= seconds:
                window.popleft()
            if len(window) >= calls:
                return False
            window.append(now)
            return True


_RATES = _RateWindow()


@define
class PendingCall:
    """An action call waiting for a person's decision."""

    id: str
    component: str
    action: str
    arguments: dict[str, Any]
    caller: str
    requested: float
    deadline: float
    decided: threading.Event = field(factory=threading.Event, repr=False)
    approved: bool = False
    decided_by: str = ""

    def to_json(self) -> dict[str, Any]:
        """What listing pending calls shows."""
        return {"id": self.id, "component": self.component, "action": self.action,
                "arguments": {k: _shown(v) for k, v in self.arguments.items()}, "caller": self.caller,
                "waiting_s": round(time.monotonic() - self.requested, 1),
                "expires_in_s": round(max(0.0, self.deadline - time.monotonic()), 1)}


class ApprovalBroker:
    """The calls of this process waiting for approval; a person decides them by id (bounded: 256 at once)."""

    MAX_PENDING = 256

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._pending: dict[str, PendingCall] = {}
        self._listeners: list[Callable[[PendingCall], None]] = []

    def add_listener(self, listener: Callable[[PendingCall], None]) -> None:
        """Call ``listener(pending)`` when a call starts waiting (an MCP server asks its client then)."""
        with self._lock:
            self._listeners.append(listener)

    def remove_listener(self, listener: Callable[[PendingCall], None]) -> None:
        """Stop calling ``listener``."""
        with self._lock:
            if listener in self._listeners:
                self._listeners.remove(listener)

    def pending(self) -> list[dict[str, Any]]:
        """The waiting calls, oldest first."""
        with self._lock:
            calls = sorted(self._pending.values(), key=lambda p: p.requested)
        return [p.to_json() for p in calls]

    def decide(self, call_id: str, approve: bool, by: str = "") -> bool:
        """Approve or deny the waiting call ``call_id``; False when no such call waits (decided or expired)."""
        with self._lock:  # decided under the lock: a call that timed out can no longer be approved
            pending = self._pending.pop(str(call_id), None)
            if pending is None:
                return False
            pending.approved, pending.decided_by = bool(approve), str(by)[:200]
            pending.decided.set()
        return True

    def wait(self, component: str, action: str, arguments: dict[str, Any], timeout: float) -> PendingCall:
        """Hold a call until it is decided or ``timeout`` passes (then it is refused: never run late)."""
        now = time.monotonic()
        call_id = _call_id.get() or uuid.uuid4().hex[:12]
        pending = PendingCall(call_id, component, action, arguments, current_caller.get(), now, now + timeout)
        with self._lock:
            if len(self._pending) >= self.MAX_PENDING:
                raise GuardrailRefused(f"{component}.{action}: {self.MAX_PENDING} calls already wait for approval")
            if call_id in self._pending:
                raise GuardrailRefused(f"{component}.{action}: approval id {call_id!r} is already waiting")
            self._pending[call_id] = pending
            listeners = list(self._listeners)
        for listener in listeners:
            with contextlib.suppress(Exception):  # a listener (an MCP session gone away) must not decide it
                listener(pending)
        pending.decided.wait(timeout)
        with self._lock:
            # Still listed: nobody decided in time (a decision after this is refused by ``decide``).
            if self._pending.pop(call_id, None) is not None:
                pending.approved = False
        return pending


_BROKER = ApprovalBroker()


def approvals() -> ApprovalBroker:
    """This process's :class:`ApprovalBroker`."""
    return _BROKER


class AuditLog:
    """One JSON object a line per action call, appended to a file (thread-safe; off until a path is set)."""

    def __init__(self, path: str | os.PathLike[str] | None = None) -> None:
        self._lock = threading.Lock()
        self._path: Path | None = None
        self._listeners: list[Callable[[dict[str, Any]], None]] = []
        if path:
            self.configure(path)

    @property
    def path(self) -> Path | None:
        """The file written to (None: off)."""
        return self._path

    def configure(self, path: str | os.PathLike[str] | None) -> None:
        """Write to ``path`` from now on (its folder is made; None turns the file off)."""
        if path is None:
            self._path = None
            return
        target = Path(path).expanduser()
        if target.exists() and not target.is_file():
            raise ConfigError(f"audit log {str(target)!r} exists and is not a regular file")
        target.parent.mkdir(parents=True, exist_ok=True)
        self._path = target

    def add_listener(self, listener: Callable[[dict[str, Any]], None]) -> None:
        """Also hand each record to ``listener`` (a topic publisher, an MCP resource)."""
        with self._lock:
            self._listeners.append(listener)

    def remove_listener(self, listener: Callable[[dict[str, Any]], None]) -> None:
        """Stop handing records to ``listener``."""
        with self._lock:
            if listener in self._listeners:
                self._listeners.remove(listener)

    @property
    def enabled(self) -> bool:
        """Whether records go anywhere (a file or a listener)."""
        return self._path is not None or bool(self._listeners)

    def write(self, record: dict[str, Any]) -> None:
        """Append ``record`` (with its time); a failing disk is reported once per call, never raised."""
        record = {"time": time.time(), **record}
        line = json.dumps(record, default=repr, allow_nan=True)
        with self._lock:
            listeners = list(self._listeners)
            path = self._path
            if path is not None:
                try:
                    with path.open("a", encoding="utf-8") as out:
                        out.write(line + "\n")
                except OSError as exc:
                    import logging  # noqa: PLC0415

                    logging.getLogger(__name__).warning("audit log %s not written: %s", path, exc)
        for listener in listeners:
            with contextlib.suppress(Exception):  # a listener must not change the call's outcome
                listener(record)


_AUDIT = AuditLog(os.environ.get("AGENTS_AUDIT_LOG") or None)


def audit_log() -> AuditLog:
    """This process's :class:`AuditLog`."""
    return _AUDIT


def configure_audit_log(path: str | os.PathLike[str] | None) -> None:
    """Write this process's audit records to ``path`` (None: stop)."""
    _AUDIT.configure(path)


@contextmanager
def with_caller(caller: str, call_id: str | None = None) -> Iterator[None]:
    """Run the enclosed action calls as ``caller`` (with the approval id ``call_id``, if given)."""
    token = current_caller.set(str(caller)[:100] or "python")
    id_token = _call_id.set(call_id)
    try:
        yield
    finally:
        _call_id.reset(id_token)
        current_caller.reset(token)


def _bound_arguments(func: Callable[..., Any], args: tuple[Any, ...], kwargs: dict[str, Any]) -> dict[str, Any]:
    try:
        bound = inspect.signature(func).bind(*args, **kwargs)
    except TypeError:
        return dict(kwargs)  # the call itself will raise the TypeError that says what is wrong
    named = dict(bound.arguments)
    named.pop("self", None)
    for param in bound.signature.parameters.values():
        if param.kind is param.VAR_KEYWORD and isinstance(named.get(param.name), dict):
            named.update(named.pop(param.name))  # **kwargs are arguments by name, each checked
    return named


#: Set for a call already admitted (rate counted, approval granted) by :func:`admit_call` before dispatch.
_admitted: contextvars.ContextVar[tuple[int, str] | None] = contextvars.ContextVar("agents_core_admitted",
                                                                                   default=None)
#: Who approved the admitted call (for its audit record on the worker).
_approved_by: contextvars.ContextVar[str] = contextvars.ContextVar("agents_core_approved_by", default="")


def _names(func: Callable[..., Any], owner: Any) -> tuple[str, str, str]:
    component = str(getattr(owner, "component_name", type(owner).__name__ if owner is not None else "?"))
    action = func.__name__
    return component, action, f"component {component!r}: action {action!r}"


def _admit(guard: ActionGuard, owner: Any, component: str, action: str, where: str, arguments: dict[str, Any],
           record: dict[str, Any], timeout: float | None = None) -> None:
    guard.check_arguments(where, arguments)
    if _admitted.get() == (id(owner), action):
        if _approved_by.get():
            record["approved_by"] = _approved_by.get()
        return  # rate and approval were settled before the call was dispatched
    if guard.rate_limit is not None and not _RATES.admit((id(owner), action), *guard.rate_limit):
        calls, seconds = guard.rate_limit
        raise GuardrailRefused(f"{where}: more than {calls} calls in {seconds:g} s; the action did not run")
    if guard.approval:
        wait = guard.approval_timeout if timeout is None else max(0.0, min(guard.approval_timeout, timeout))
        pending = _BROKER.wait(component, action, arguments, wait)
        record["approval_id"] = pending.id
        if not pending.decided.is_set():
            raise GuardrailRefused(f"{where}: not approved within {wait:g} s; the action did not run")
        if not pending.approved:
            by = f" by {pending.decided_by}" if pending.decided_by else ""
            raise GuardrailRefused(f"{where}: denied{by}; the action did not run")
        record["approved_by"] = pending.decided_by


def _record(component: str, action: str, arguments: dict[str, Any]) -> dict[str, Any]:
    return {"caller": current_caller.get(), "component": component, "action": action,
            "arguments": {k: _short(v) for k, v in arguments.items()}}


@define(frozen=True)
class Admission:
    """A call settled by :func:`admit_call`: :meth:`run` runs it on another thread as its caller, admitted."""

    caller: str
    call_id: str | None
    admitted: tuple[int, str] | None
    approved_by: str = ""

    def run(self, func: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        """``func(*args, **kwargs)`` with this admission's caller (and admission) set for the call only."""
        tokens = (current_caller.set(self.caller), _call_id.set(self.call_id), _admitted.set(self.admitted))
        by_token = _approved_by.set(self.approved_by)
        try:
            return func(*args, **kwargs)
        finally:
            _approved_by.reset(by_token)
            _admitted.reset(tokens[2])
            _call_id.reset(tokens[1])
            current_caller.reset(tokens[0])


def admit_call(func: Callable[..., Any], owner: Any, args: Sequence[Any], kwargs: Mapping[str, Any],
               timeout: float) -> Admission:
    """Settle a call's guardrails before it is dispatched to its component's worker (a service's request).

    An approval waits here, on the request's thread and at most ``timeout`` seconds, so that the
    worker is never held and a call whose caller gave up never runs. Returns what runs the call
    on the worker (with the caller and the admission). Raises :class:`GuardrailRefused`.
    """
    admitted: tuple[int, str] | None = None
    approved_by = ""
    guard = getattr(func, "_agents_action_guard", None)
    if isinstance(guard, ActionGuard) and guard.active:
        target = getattr(func, "__wrapped__", func)
        component, action, where = _names(target, owner)
        arguments = _bound_arguments(target, (owner, *args), dict(kwargs))
        record = _record(component, action, arguments)
        try:
            _admit(guard, owner, component, action, where, arguments, record, timeout)
        except GuardrailRefused as exc:
            _AUDIT.write({**record, "decision": "refused", "outcome": str(exc)})
            raise
        admitted = (id(owner), action)
        approved_by = str(record.get("approved_by", ""))
    return Admission(current_caller.get(), _call_id.get(), admitted, approved_by)


def run_guarded(func: Callable[..., Any], guard: ActionGuard | None, args: tuple[Any, ...],
                kwargs: dict[str, Any]) -> Any:
    """Call the action ``func(*args, **kwargs)`` (``args[0]`` its component) through its guardrails, audited."""
    if (guard is None or not guard.active) and not _AUDIT.enabled:
        return func(*args, **kwargs)  # nothing to check or record: no cost beyond this test
    owner = args[0] if args else None
    component, action, where = _names(func, owner)
    arguments = _bound_arguments(func, args, kwargs)
    record = _record(component, action, arguments)
    if guard is not None and guard.active:
        try:
            _admit(guard, owner, component, action, where, arguments, record)
        except GuardrailRefused as exc:
            _AUDIT.write({**record, "decision": "refused", "outcome": str(exc)})
            raise
    try:
        result = func(*args, **kwargs)
    except Exception as exc:
        _AUDIT.write({**record, "decision": "allowed", "outcome": f"error: {type(exc).__name__}: {exc}"[:500]})
        raise
    _AUDIT.write({**record, "decision": "allowed", "outcome": "ok"})
    return result
