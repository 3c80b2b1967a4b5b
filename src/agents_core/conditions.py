"""Conditions over message fields, for events: ``topic.msg.data > 5``.

``Topic.msg`` returns a :class:`FieldRef`; attribute access walks into the message's fields and
comparisons build a :class:`Condition`. Conditions combine with ``&``, ``|`` and ``~``. A field
reference can also stand for a value in an :class:`~agents_core.actions.Action`'s arguments, to
pass part of the triggering message to the action.

For simple types carried as builtins (String, Bool, Int32, Float64, multi-arrays), the message
itself is the field ``data`` (as in the ROS messages of the same name).

The operators of upstream's field references work as written there: ``is_in`` / ``not_in``,
``contains`` / ``not_contains`` (a str, or with a list: all / not all of its items),
``contains_any`` / ``contains_all`` / ``not_contains_any`` / ``not_contains_all`` (a list field
against a list of items, e.g. ``detections.msg.labels.contains_any(["person"])``),
``is_true`` / ``is_false``, ``~ref`` (the field is False) and ``ref[i]`` (an item of an array field).
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any

import attrs

from .errors import ConfigError
from .support.lazy_numpy import is_ndarray, np

if TYPE_CHECKING:
    from .topics import Topic

__all__ = ["Condition", "FieldRef"]


class FieldRef:
    """A path into the message of a topic, e.g. ``topic.msg.header.frame_id``."""

    __slots__ = ("path", "topic")

    def __init__(self, topic: Topic, path: tuple[str | int, ...]) -> None:
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
                value = value[name] if isinstance(name, int) else getattr(value, name)
            except (AttributeError, IndexError, TypeError, KeyError):
                raise ConfigError(
                    f"topic {self.topic.name!r}: message has no field {_dotted(self.path[: i + 1])!r}"
                ) from None
        return value

    def __getitem__(self, index: int) -> FieldRef:
        """An item of an array field: ``topic.msg.data[0] > 5``."""
        if isinstance(index, bool) or not isinstance(index, int):
            raise ConfigError(f"{self}: only int indices select an item of a field, got {index!r}")
        return FieldRef(self.topic, (*self.path, index))

    def _compare(self, op: Callable[[Any, Any], Any], symbol: str, other: Any) -> Condition:
        return Condition(lambda values: bool(op(self.resolve(values[self.topic.name]), other)),
                         f"{self} {symbol} {other!r}", {self.topic.name: self.topic},
                         recipe=("compare", self.topic, self.path, symbol, other))

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

    def not_in(self, values: Iterable[Any]) -> Condition:
        """True when the field's value is none of ``values``."""
        options = list(values)
        return self._compare(lambda a, b: not any(_equal(a, x) for x in b), "not in", options)

    def contains(self, item: Any) -> Condition:
        """True when the field (a str, list or array) contains ``item``; with a list or tuple of items,
        when it contains all of them (as upstream's ``contains``)."""
        if isinstance(item, list | tuple):
            return self.contains_all(item)
        return self._compare(lambda a, b: b in _items(a), "contains", item)

    def not_contains(self, item: Any) -> Condition:
        """The negation of :meth:`contains`: with a list or tuple, True when at least one item is missing."""
        if isinstance(item, list | tuple):
            return self.not_contains_all(item)
        return self._compare(lambda a, b: b not in _items(a), "not contains", item)

    def contains_any(self, items: Iterable[Any]) -> Condition:
        """True when the field (a list or array; a single value counts as a list of one) holds at least one
        of ``items``: ``detections.msg.labels.contains_any(["person", "dog"])``."""
        return self._compare(lambda a, b: any(x in _items(a) for x in b), "contains any of", _listed(items))

    def contains_all(self, items: Iterable[Any]) -> Condition:
        """True when the field holds every one of ``items``."""
        return self._compare(lambda a, b: all(x in _items(a) for x in b), "contains all of", _listed(items))

    def not_contains_any(self, items: Iterable[Any]) -> Condition:
        """True when the field holds none of ``items``."""
        return self._compare(lambda a, b: not any(x in _items(a) for x in b), "contains none of",
                             _listed(items))

    def not_contains_all(self, items: Iterable[Any]) -> Condition:
        """True when at least one of ``items`` is missing from the field."""
        return self._compare(lambda a, b: not all(x in _items(a) for x in b), "misses one of", _listed(items))

    def is_true(self) -> Condition:
        """True when the (bool) field is True."""
        return self._compare(lambda a, b: bool(a) is b, "is", True)

    def is_false(self) -> Condition:
        """True when the (bool) field is False."""
        return self._compare(lambda a, b: bool(a) is b, "is", False)

    def __invert__(self) -> Condition:
        """``~topic.msg.flag``: the field is False (upstream's shorthand)."""
        return self.is_false()

    def __repr__(self) -> str:
        return _dotted((f"{self.topic.name}.msg", *self.path))


def _dotted(path: tuple[str | int, ...]) -> str:
    return "".join(f"[{p}]" if isinstance(p, int) else (f".{p}" if i else p) for i, p in enumerate(path))


def _listed(items: Iterable[Any]) -> list[Any]:
    if isinstance(items, str):
        # A str is an iterable of characters: contains_any("person") would match any letter.
        raise ConfigError(f"expected a list of items, got the str {items!r}: write [{items!r}]")
    return list(items)


def _items(value: Any) -> Any:
    """The field as a container: arrays as lists (``in`` on an array compares element-wise), a scalar as a list
    of one (as upstream)."""
    if is_ndarray(value):
        return value.tolist()
    if isinstance(value, str | list | tuple | set | frozenset | dict):
        return value
    return [value]


def _equal(a: Any, b: Any) -> bool:
    if is_ndarray(a) or is_ndarray(b):
        return bool(np.array_equal(a, b))
    return bool(a == b)


class Condition:
    """A boolean function of the latest messages of one or more topics."""

    __slots__ = ("_fn", "description", "recipe", "topics")

    def __init__(self, fn: Callable[[Mapping[str, Any]], bool], description: str,
                 topics: dict[str, Topic], recipe: tuple[Any, ...] | None = None) -> None:
        self._fn = fn
        self.description = description
        self.topics = topics
        #: How the condition was built, as data (``("compare", topic, path, symbol, value)``, ``("and", a, b)``,
        #: ``("or", a, b)``, ``("not", a)``), so another process can build it again
        #: (:mod:`agents_core.declarations.event_transfer`); None for a condition made from a function.
        self.recipe = recipe

    def evaluate(self, values: Mapping[str, Any]) -> bool:
        """Evaluate on ``{topic name: latest value}``; False while any needed topic has no value yet."""
        if any(name not in values for name in self.topics):
            return False
        return self._fn(values)

    def __and__(self, other: Condition) -> Condition:
        return Condition(lambda v: self._fn(v) and other._fn(v), f"({self.description}) & ({other.description})",
                         {**self.topics, **other.topics}, recipe=_combined("and", self, other))

    def __or__(self, other: Condition) -> Condition:
        return Condition(lambda v: self._fn(v) or other._fn(v), f"({self.description}) | ({other.description})",
                         {**self.topics, **other.topics}, recipe=_combined("or", self, other))

    def __invert__(self) -> Condition:
        return Condition(lambda v: not self._fn(v), f"~({self.description})", dict(self.topics),
                         recipe=("not", self.recipe) if self.recipe is not None else None)

    def __bool__(self) -> bool:
        raise ConfigError(
            f"condition {self.description!r} has no truth value in Python code; combine conditions "
            "with &, |, ~ (not 'and', 'or', 'not') and pass it to an Event"
        )

    def __repr__(self) -> str:
        return f"Condition({self.description})"


def _combined(kind: str, a: Condition, b: Condition) -> tuple[Any, ...] | None:
    if a.recipe is None or b.recipe is None:
        return None
    return (kind, a.recipe, b.recipe)
