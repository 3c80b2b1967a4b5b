"""Conditions over message fields, for events: ``topic.msg.data > 5``.

``Topic.msg`` returns a :class:`FieldRef`; attribute access walks into the message's fields and
comparisons build a :class:`Condition`. Conditions combine with ``&``, ``|`` and ``~``. A field
reference can also stand for a value in an :class:`~agents_core.actions.Action`'s arguments, to
pass part of the triggering message to the action.

For simple types carried as builtins (String, Bool, Int32, Float64, multi-arrays), the message
itself is the field ``data`` (as in the ROS messages of the same name).
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any

import attrs
import numpy as np

from .errors import ConfigError

if TYPE_CHECKING:
    from .topics import Topic

__all__ = ["Condition", "FieldRef"]


class FieldRef:
    """A path into the message of a topic, e.g. ``topic.msg.header.frame_id``."""

    __slots__ = ("path", "topic")

    def __init__(self, topic: Topic, path: tuple[str, ...]) -> None:
        self.topic = topic
        self.path = path

    def __getattr__(self, name: str) -> FieldRef:
        if name.startswith("__"):
            raise AttributeError(name)
        if not self.path:
            value_class = self.topic.msg_type.value_class
            if attrs.has(value_class):
                names = {f.name for f in attrs.fields(value_class)}
                if name not in names:
                    raise ConfigError(
                        f"topic {self.topic.name!r} ({self.topic.type_name}) has no field {name!r}; "
                        f"fields: {sorted(names)}"
                    )
            elif name != "data":
                raise ConfigError(
                    f"topic {self.topic.name!r} ({self.topic.type_name}) carries a plain value: use '.data'"
                )
        return FieldRef(self.topic, (*self.path, name))

    def resolve(self, value: Any) -> Any:
        """Read this field out of a message value of the topic."""
        for i, name in enumerate(self.path):
            if i == 0 and name == "data" and not attrs.has(type(value)):
                continue
            try:
                value = getattr(value, name)
            except AttributeError:
                raise ConfigError(
                    f"topic {self.topic.name!r}: message has no field {'.'.join(self.path[: i + 1])!r}"
                ) from None
        return value

    def _compare(self, op: Callable[[Any, Any], Any], symbol: str, other: Any) -> Condition:
        return Condition(lambda values: bool(op(self.resolve(values[self.topic.name]), other)),
                         f"{self} {symbol} {other!r}", {self.topic.name: self.topic})

    def __eq__(self, other: object) -> Condition:  # type: ignore[override]
        return self._compare(_equal, "==", other)

    def __ne__(self, other: object) -> Condition:  # type: ignore[override]
        return self._compare(lambda a, b: not _equal(a, b), "!=", other)

    def __lt__(self, other: Any) -> Condition:
        return self._compare(operator.lt, "<", other)

    def __le__(self, other: Any) -> Condition:
        return self._compare(operator.le, "<=", other)

    def __gt__(self, other: Any) -> Condition:
        return self._compare(operator.gt, ">", other)

    def __ge__(self, other: Any) -> Condition:
        return self._compare(operator.ge, ">=", other)

    __hash__ = None  # type: ignore[assignment]  # == builds a Condition, so refs are not hashable

    def is_in(self, values: Iterable[Any]) -> Condition:
        """True when the field's value is one of ``values``."""
        options = list(values)
        return self._compare(lambda a, b: any(_equal(a, x) for x in b), "in", options)

    def contains(self, item: Any) -> Condition:
        """True when the field (a str, list or array) contains ``item``."""
        return self._compare(lambda a, b: b in a, "contains", item)

    def __repr__(self) -> str:
        return ".".join((f"{self.topic.name}.msg", *self.path))


def _equal(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return bool(np.array_equal(a, b))
    return bool(a == b)


class Condition:
    """A boolean function of the latest messages of one or more topics."""

    __slots__ = ("_fn", "description", "topics")

    def __init__(self, fn: Callable[[Mapping[str, Any]], bool], description: str,
                 topics: dict[str, Topic]) -> None:
        self._fn = fn
        self.description = description
        self.topics = topics

    def evaluate(self, values: Mapping[str, Any]) -> bool:
        """Evaluate on ``{topic name: latest value}``; False while any needed topic has no value yet."""
        if any(name not in values for name in self.topics):
            return False
        return self._fn(values)

    def __and__(self, other: Condition) -> Condition:
        return Condition(lambda v: self._fn(v) and other._fn(v), f"({self.description}) & ({other.description})",
                         {**self.topics, **other.topics})

    def __or__(self, other: Condition) -> Condition:
        return Condition(lambda v: self._fn(v) or other._fn(v), f"({self.description}) | ({other.description})",
                         {**self.topics, **other.topics})

    def __invert__(self) -> Condition:
        return Condition(lambda v: not self._fn(v), f"~({self.description})", dict(self.topics))

    def __bool__(self) -> bool:
        raise ConfigError(
            f"condition {self.description!r} has no truth value in Python code; combine conditions "
            "with &, |, ~ (not 'and', 'or', 'not') and pass it to an Event"
        )

    def __repr__(self) -> str:
        return f"Condition({self.description})"
