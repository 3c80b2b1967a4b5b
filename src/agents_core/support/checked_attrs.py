"""Typed attrs classes: every field checked against its annotation, misspelt arguments named.

Configs, model descriptions and QoS settings arrive from recipes, files and remote
``set_param`` calls. attrs alone accepts ``history_size=2.5`` for an ``int`` field and raises a
bare ``TypeError`` for a misspelt keyword; a setting that is accepted but wrong fails much later,
on the robot. A class whose metaclass is :class:`CheckedFieldsMeta` instead:

- checks every field against its annotation at construction and on every assignment (an ``int``
  field refuses ``2.5`` and ``True``; a ``bool`` refuses ``"no"``; a ``float`` refuses NaN and
  infinities; ``Literal[...]`` and unions are honoured), raising
  :class:`~agents_core.errors.ConfigError` that names the class and the field;
- raises :class:`~agents_core.errors.ConfigError` naming a misspelt keyword argument, with a
  "did you mean" when one field is close.

Annotations the checker does not understand (classes of the user's own, ``Any``, callables)
are left to the field's own validators.
"""

from __future__ import annotations

import difflib
import math
import types
import typing
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Literal, Union

import attrs

from ..errors import ConfigError, PositionalArgumentsError

__all__ = ["CheckedFieldsMeta", "check_declared_type", "describe_annotation", "name_hints"]

_COUNTING_ATTR = type(attrs.field())
_hints_cache: dict[type, dict[str, Any]] = {}


def _hints(cls: type) -> dict[str, Any]:
    hints = _hints_cache.get(cls)
    if hints is None:
        try:
            hints = typing.get_type_hints(cls)
        except Exception:  # an annotation naming something not importable here: skip checking it
            hints = {}
        _hints_cache[cls] = hints
    return hints


def describe_annotation(annotation: Any) -> str:
    """A short human form of a field annotation (``int``, ``str or None``, ``one of ['a', 'b']``)."""
    origin = typing.get_origin(annotation)
    if origin is Literal:
        return f"one of {list(typing.get_args(annotation))}"
    if origin in (Union, types.UnionType):
        return " or ".join(describe_annotation(a) for a in typing.get_args(annotation))
    if annotation is type(None):
        return "None"
    if isinstance(annotation, type):
        return annotation.__name__
    return str(annotation)


def _fits(annotation: Any, value: Any) -> bool | None:
    """Whether ``value`` fits ``annotation``; None when the annotation is not one we check."""
    if annotation is Any:
        return None
    origin = typing.get_origin(annotation)
    if origin is Literal:
        return any(value == option and type(value) is type(option) for option in typing.get_args(annotation))
    if origin in (Union, types.UnionType):
        verdicts = [_fits(a, value) for a in typing.get_args(annotation)]
        if any(v is True for v in verdicts):
            return True
        return None if any(v is None for v in verdicts) else False
    if annotation is type(None):
        return value is None
    if annotation is bool:
        return isinstance(value, bool)
    if annotation is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if annotation is float:
        return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    if annotation is str:
        return isinstance(value, str)
    if origin is not None:
        if origin in (dict, Mapping, typing.Mapping):
            return isinstance(value, Mapping)
        if origin in (list, tuple, Sequence, typing.Sequence):
            return isinstance(value, list | tuple)
        return None
    if annotation in (dict, list, tuple):
        return isinstance(value, annotation)
    return None


def check_declared_type(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    """attrs validator: ``value`` must fit the field's annotation (see the module docstring)."""
    annotation = _hints(type(instance)).get(attribute.name)
    if annotation is None:
        return
    if _fits(annotation, value) is False:
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must be {describe_annotation(annotation)}, "
                          f"got {value!r} ({type(value).__name__})")


def _is_classvar(annotation: Any) -> bool:
    text = annotation if isinstance(annotation, str) else repr(annotation)
    return "ClassVar" in text


def name_hints(unknown: Iterable[str], known: Iterable[str]) -> str:
    """``'stauts_rate' (did you mean 'status_rate'?), 'x'``: unknown names, each with its close match.

    One wording for every place that refuses a field name: constructors, ``from_dict``, ``update``
    and the sections of config files.
    """
    choices = sorted(known)
    hints = []
    for word in unknown:
        close = difflib.get_close_matches(word, choices, n=1)
        hints.append(f"{word!r}" + (f" (did you mean {close[0]!r}?)" if close else ""))
    return ", ".join(hints)


class CheckedFieldsMeta(type):
    """Metaclass of attrs classes with checked fields (see the module docstring).

    Put it on a base class; every ``@attrs.define`` subclass then checks its own fields too.
    """

    def __new__(mcs, name: str, bases: tuple[type, ...], namespace: dict[str, Any], **kwargs: Any) -> Any:
        # attrs re-creates slotted classes from a finished one; those carry __attrs_attrs__
        # and their fields are already set up.
        if "__attrs_attrs__" not in namespace:
            for field_name, annotation in namespace.get("__annotations__", {}).items():
                if _is_classvar(annotation) or field_name.startswith("__"):
                    continue
                current = namespace.get(field_name, attrs.NOTHING)
                if isinstance(current, _COUNTING_ATTR):
                    current.validator(check_declared_type)
                elif current is attrs.NOTHING:
                    namespace[field_name] = attrs.field(validator=check_declared_type)
                elif not isinstance(current, property | classmethod | staticmethod | types.FunctionType):
                    namespace[field_name] = attrs.field(default=current, validator=check_declared_type)
        return super().__new__(mcs, name, bases, namespace, **kwargs)

    def __call__(cls, *args: Any, **kwargs: Any) -> Any:
        if attrs.has(cls):
            known = {a.alias for a in attrs.fields(cls) if a.init}
            unknown = sorted(set(kwargs) - known)
            if unknown:
                raise ConfigError(f"{cls.__name__}: unknown argument(s) {name_hints(unknown, known)}; "
                                  f"known: {sorted(known)}")
        try:
            return super().__call__(*args, **kwargs)
        except TypeError as exc:
            # Missing required or extra positional arguments: attrs' own message, as a ConfigError
            # that is still the TypeError attrs promises.
            if "__init__()" in str(exc):
                raise PositionalArgumentsError(f"{cls.__name__}: {exc}") from exc
            raise
