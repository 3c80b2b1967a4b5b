"""Actions, fallbacks, and the decorators that expose component methods to them.

``Action(method, args, kwargs, description=...)`` wraps a callable to run when an event fires or
a component fails; ``description`` is free text for people and planners (Cortex shows it).
Arguments may be field references such as ``topic.msg.data``: they are replaced by the matching
part of the message that fired the event. An action whose method belongs to a
component runs on that component's serial worker, never concurrently with its steps.

``@component_action`` marks a method that outside callers may run through the component's
``execute_method`` service (an allow-list: nothing else is callable); its description follows
the OpenAI tool format so a language model can be given the same list. ``@component_fallback``
marks a method meant for ``on_*_fail`` handlers.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping, Sequence
from typing import Any, TypeVar, overload

from .conditions import FieldRef
from .declarations.action_schema import describe_action
from .errors import ConfigError
from .guardrails import DEFAULT_APPROVAL_TIMEOUT, ActionGuard, run_guarded
from .telemetry import switch as _telemetry

__all__ = ["Action", "Fallback", "component_action", "component_fallback"]

F = TypeVar("F", bound=Callable[..., Any])

ACTION_MARK = "_agents_component_action"
FALLBACK_MARK = "_agents_component_fallback"
#: The attribute holding an action's :class:`~agents_core.guardrails.ActionGuard`.
GUARD_MARK = "_agents_action_guard"


class Action:
    """A deferred call: ``method(*args, **kwargs)``, with message fields resolved at run time."""

    def __init__(self, method: Callable[..., Any], args: Sequence[Any] | Any = (),
                 kwargs: Mapping[str, Any] | None = None, description: str | None = None) -> None:
        if not callable(method):
            raise ConfigError(f"Action method must be callable, got {type(method).__name__}")
        if description is not None and not isinstance(description, str):
            raise ConfigError(f"Action description must be a str, got {type(description).__name__}")
        self.method = method
        #: What the action does, in words (upstream's ``Action(..., description=...)``); None if not given.
        self.description = description
        self.args = tuple(args) if isinstance(args, list | tuple) else (args,)
        self.kwargs = dict(kwargs or {})

    @property
    def owner(self) -> Any:
        """The object the method is bound to (a component, for component methods), else None."""
        return getattr(self.method, "__self__", None)

    @property
    def name(self) -> str:
        """The method's name."""
        return getattr(self.method, "__name__", type(self.method).__name__)

    @property
    def topics(self) -> dict[str, Any]:
        """Topics whose messages the arguments refer to."""
        refs = [a for a in (*self.args, *self.kwargs.values()) if isinstance(a, FieldRef)]
        return {r.topic.name: r.topic for r in refs}

    def resolve(self, values: Mapping[str, Any] | None = None) -> tuple[tuple[Any, ...], dict[str, Any]]:
        """The concrete arguments, with field references read from ``values`` (topic name -> message)."""
        values = values or {}

        def one(arg: Any) -> Any:
            if isinstance(arg, FieldRef):
                if arg.topic.name not in values:
                    raise ConfigError(f"action {self.name!r} needs a message from topic {arg.topic.name!r}, "
                                      "which the firing event did not carry")
                return arg.resolve(values[arg.topic.name])
            return arg

        return tuple(one(a) for a in self.args), {k: one(v) for k, v in self.kwargs.items()}

    def __call__(self, values: Mapping[str, Any] | None = None) -> Any:
        args, kwargs = self.resolve(values)
        tel = _telemetry.hooks
        if tel is None:
            return self.method(*args, **kwargs)
        with tel.call("action", self.name):
            return self.method(*args, **kwargs)

    def __repr__(self) -> str:
        return f"Action({self.name}, args={self.args!r}, kwargs={self.kwargs!r})"


class Fallback:
    """What a component does when it fails: try each action up to ``max_retries`` times, in order.

    ``max_retries=None`` retries the last action forever; once every action is used up the
    component gives up (and runs its ``on_giveup`` actions once).
    """

    def __init__(self, actions: Action | Sequence[Action], max_retries: int | None = None) -> None:
        self.actions = [actions] if isinstance(actions, Action) else list(actions)
        if not self.actions or not all(isinstance(a, Action) for a in self.actions):
            raise ConfigError("a fallback needs one or more Action objects")
        if max_retries is not None and (isinstance(max_retries, bool) or not isinstance(max_retries, int)
                                        or max_retries < 1):
            raise ConfigError(f"max_retries must be a positive int or None, got {max_retries!r}")
        self.max_retries = max_retries
        self._index = 0
        self._tries = 0

    def next_action(self) -> Action | None:
        """The action to run for this failure, or None when the fallback is exhausted."""
        if self._index >= len(self.actions):
            return None
        action = self.actions[self._index]
        self._tries += 1
        last = self._index == len(self.actions) - 1
        limit = self.max_retries if self.max_retries is not None else (None if last else 1)
        if limit is not None and self._tries >= limit:
            self._index += 1
            self._tries = 0
        return action

    def reset(self) -> None:
        """Start again from the first action (called when the component is healthy again)."""
        self._index = 0
        self._tries = 0


def _description_for(func: Callable[..., Any], description: Mapping[str, Any] | None) -> dict[str, Any]:
    if description is not None and "name" in description and "function" not in description:
        return dict(description)
    # The parameters from the signature, annotations and docstring (agents_core.declarations.action_schema).
    return describe_action(func, description)


def _with_guardrails(described: dict[str, Any], guard: ActionGuard) -> dict[str, Any]:
    """The description a model reads, saying the guardrails: limits as JSON Schema bounds, the rest in words."""
    if not guard.active:
        return described
    function = dict(described.get("function", {}))
    schema = function.get("parameters")
    if isinstance(schema, dict) and isinstance(schema.get("properties"), dict):
        properties = {k: dict(v) if isinstance(v, dict) else v for k, v in schema["properties"].items()}
        for name, (low, high) in guard.limits.items():
            entry = properties.get(name)
            if isinstance(entry, dict):
                target = entry.setdefault("items", {}) if entry.get("type") == "array" else entry
                target["minimum"], target["maximum"] = low, high
        function["parameters"] = {**schema, "properties": properties}
    notes = []
    if guard.approval:
        notes.append("Each call waits for a person's approval.")
    if guard.rate_limit is not None:
        notes.append(f"At most {guard.rate_limit[0]} calls in {guard.rate_limit[1]:g} s.")
    if notes:
        function["description"] = " ".join([str(function.get("description", "")).strip(), *notes]).strip()
    return {**described, "function": function}


@overload
def component_action(func: F, /) -> F: ...
@overload
def component_action(*, description: Mapping[str, Any] | None = None,
                     limits: Mapping[str, tuple[float, float]] | None = None, approval: bool = False,
                     approval_timeout: float = DEFAULT_APPROVAL_TIMEOUT,
                     rate_limit: tuple[int, float] | None = None) -> Callable[[F], F]: ...


def component_action(func: Any = None, /, *, description: Mapping[str, Any] | None = None,
                     limits: Mapping[str, tuple[float, float]] | None = None, approval: bool = False,
                     approval_timeout: float = DEFAULT_APPROVAL_TIMEOUT,
                     rate_limit: tuple[int, float] | None = None) -> Any:
    """Mark a component method as callable by actions and the ``execute_method`` service.

    ``description`` is an OpenAI-style tool description (``{"description": ..., "parameters":
    {...}}``, or the full ``{"type": "function", "function": {...}}``); by default it is built
    from the method's name, signature and docstring.

    Guardrails (:mod:`agents_core.guardrails`), checked for every caller before the method runs:
    ``limits={"speed": (0.0, 0.5)}`` bounds numeric arguments, ``approval=True`` holds each call
    until a person approves it (refused after ``approval_timeout`` seconds), ``rate_limit=(calls,
    seconds)`` bounds how often it runs.
    """
    guard = ActionGuard(limits=limits, approval=approval, approval_timeout=approval_timeout,
                        rate_limit=rate_limit)

    def mark(f: F) -> F:
        @functools.wraps(f)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            return run_guarded(f, guard, args, kwargs)

        described = _with_guardrails(_description_for(f, description), guard)
        setattr(wrapper, ACTION_MARK, described)
        setattr(wrapper, GUARD_MARK, guard)
        return wrapper  # type: ignore[return-value]

    return mark(func) if func is not None else mark


@overload
def component_fallback(func: F, /) -> F: ...
@overload
def component_fallback(*, description: Mapping[str, Any] | None = None) -> Callable[[F], F]: ...


def component_fallback(func: Any = None, /, *, description: Mapping[str, Any] | None = None) -> Any:
    """Mark a component method as a fallback (it is also callable as a component action)."""

    def mark(f: F) -> F:
        marked = component_action(description=description)(f)
        setattr(marked, FALLBACK_MARK, True)
        return marked

    return mark(func) if func is not None else mark
