"""The ``pre_defined`` points of a map or memory layer: ``(position, text)`` pairs written once.

:class:`~agents_core.components.MapLayer` and :class:`~agents_core.components.memory.MemLayer`
take them alike, so they are checked here once: a position is ``(x, y)`` or ``(x, y, z)`` of
finite numbers (a numpy array too, as upstream's recipes give), the text is not empty, and each
refusal names the layer class and the point's index.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any

from ..errors import ConfigError

__all__ = ["convert_points", "position_of", "pre_defined_validator"]


def position_of(point: Any, what: str) -> tuple[float, float, float]:
    """``point`` ((x, y) or (x, y, z)) as three finite floats (z 0.0 when absent), else ConfigError naming ``what``."""
    try:
        values = [float(v) for v in point]
    except (TypeError, ValueError):
        raise ConfigError(f"{what} must be a sequence (x, y[, z]) of numbers, got {point!r:.100}") from None
    if len(values) not in (2, 3) or not all(math.isfinite(v) for v in values):
        raise ConfigError(f"{what} must be (x, y) or (x, y, z) of finite numbers, got {point!r:.100}")
    return values[0], values[1], values[2] if len(values) == 3 else 0.0


def _as_float_point(point: Any) -> Any:
    # Positions become tuples of floats, so that a layer can be sent to a component process; a
    # malformed point is left as it is, for the validator to name.
    if not (isinstance(point, tuple | list) and len(point) == 2 and isinstance(point[0], Iterable)
            and not isinstance(point[0], str | bytes)):
        return point
    try:
        return (tuple(float(v) for v in point[0]), point[1])
    except (TypeError, ValueError):
        return point


def convert_points(owner: str, value: Any) -> list[tuple[Any, str]]:
    """``<owner>.pre_defined`` as given (any iterable of points) as a list of tuples; the layer's
    converter calls this with its own class name (attrs converters must be named functions for mypy)."""
    if isinstance(value, str | bytes) or not isinstance(value, Iterable):
        raise ConfigError(f"{owner}.pre_defined must be a list of (position, text), got {value!r:.100}")
    return [_as_float_point(point) for point in value]


def pre_defined_validator(owner: str) -> Callable[[Any, Any, Any], None]:
    """The attrs validator of ``<owner>.pre_defined``: each point a (position, non-empty text)."""

    def check(instance: Any, attribute: Any, value: Any) -> None:
        for i, point in enumerate(value):
            if not (isinstance(point, tuple | list) and len(point) == 2 and isinstance(point[1], str)
                    and point[1].strip()):
                raise ConfigError(f"{owner}.pre_defined[{i}] must be (position, non-empty text), got {point!r:.100}")
            position_of(point[0], f"{owner}.pre_defined[{i}] position")

    return check
