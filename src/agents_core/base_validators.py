"""attrs validators for config and model fields, raising :class:`~agents_core.errors.ConfigError`.

Use them as ``field(default=1.0, validator=base_validators.gt(0.0))``. Each error names the class
and the field, and says what was expected.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection
from typing import Any

import attrs

from .errors import ConfigError

__all__ = ["ge", "gt", "in_", "in_range", "le", "list_contained_in", "lt", "non_empty_str", "optional_str"]

Validator = Callable[[Any, "attrs.Attribute[Any]", Any], None]


def _where(instance: Any, attribute: attrs.Attribute[Any]) -> str:
    return f"{type(instance).__name__}.{attribute.name}"


def _numeric(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"{_where(instance, attribute)} must be a number, got {value!r}")
    # NaN compares False with every bound and inf passes a lower one: neither is a setting.
    if not math.isfinite(value):
        raise ConfigError(f"{_where(instance, attribute)} must be a finite number, got {value!r}")


def _bound(check: Callable[[Any], bool], text: str) -> Validator:
    def validate(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
        if value is None and attribute.default is None:
            return
        _numeric(instance, attribute, value)
        if not check(value):
            raise ConfigError(f"{_where(instance, attribute)} must be {text}, got {value!r}")

    return validate


def gt(bound: float) -> Validator:
    """Value must be greater than ``bound``."""
    return _bound(lambda v: v > bound, f"> {bound}")


def ge(bound: float) -> Validator:
    """Value must be at least ``bound``."""
    return _bound(lambda v: v >= bound, f">= {bound}")


def lt(bound: float) -> Validator:
    """Value must be less than ``bound``."""
    return _bound(lambda v: v < bound, f"< {bound}")


def le(bound: float) -> Validator:
    """Value must be at most ``bound``."""
    return _bound(lambda v: v <= bound, f"<= {bound}")


def in_range(min_value: float, max_value: float) -> Validator:
    """Value must lie in the closed interval [min_value, max_value]."""
    return _bound(lambda v: min_value <= v <= max_value, f"in [{min_value}, {max_value}]")


def in_(options: Collection[Any]) -> Validator:
    """Value must be one of ``options``."""
    allowed = list(options)

    def validate(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
        if value not in allowed:
            raise ConfigError(f"{_where(instance, attribute)} must be one of {allowed}, got {value!r}")

    return validate


def list_contained_in(options: Collection[Any]) -> Validator:
    """Every item of the (list) value must be one of ``options``."""
    allowed = list(options)

    def validate(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
        bad = [v for v in value if v not in allowed]
        if bad:
            raise ConfigError(f"{_where(instance, attribute)}: {bad} not among {allowed}")

    return validate


def optional_str(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    """Value must be a ``str`` or ``None`` (used as is: ``validator=base_validators.optional_str``)."""
    if value is not None and not isinstance(value, str):
        raise ConfigError(f"{_where(instance, attribute)} must be a str or None, got {value!r}")


def non_empty_str(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    """Value must be a non-empty ``str`` (used as is: ``validator=base_validators.non_empty_str``)."""
    if not isinstance(value, str) or not value:
        raise ConfigError(f"{_where(instance, attribute)} must be a non-empty str, got {value!r}")
