"""A value summarised for people: JSON-ready data, with large arrays and byte strings reduced to their size.

Large arrays and byte strings (images, audio, point clouds) are never shown whole: they become
``{"shape": [...], "dtype": "..."}`` or ``{"bytes": n}``, so an echo of a camera topic stays
readable. Everything else is turned into JSON-ready data field by field. Used by ``agentsctl
topics echo`` (:mod:`agents_core.cli.values`) and the Foxglove feeds.
"""

from __future__ import annotations

import enum
import math
from typing import Any

import attrs
import numpy as np

__all__ = ["MAX_INLINE_ELEMENTS", "MAX_INLINE_TEXT", "summarize"]

#: Arrays with more elements than this are shown as shape and dtype only.
MAX_INLINE_ELEMENTS = 16
#: Strings longer than this are cut (with their length shown).
MAX_INLINE_TEXT = 2000
_MAX_DEPTH = 8


def summarize(value: Any, depth: int = 0) -> Any:
    """JSON-ready data for ``value``, with large arrays and bytes reduced to a summary."""
    if depth > _MAX_DEPTH:
        return repr(value)[:80]
    if value is None or isinstance(value, bool | int):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else str(value)
    if isinstance(value, str):
        return value if len(value) <= MAX_INLINE_TEXT else f"{value[:MAX_INLINE_TEXT]}... ({len(value)} chars)"
    if isinstance(value, enum.Enum):
        return summarize(value.value, depth + 1)
    if isinstance(value, bytes | bytearray | memoryview):
        return {"bytes": len(value)}
    if isinstance(value, np.generic):
        return summarize(value.item(), depth + 1)
    if isinstance(value, np.ndarray):
        if value.size <= MAX_INLINE_ELEMENTS and value.dtype.kind in "biuf":
            return [summarize(v, depth + 1) for v in value.tolist()] if value.ndim else summarize(value.item())
        return {"shape": list(value.shape), "dtype": str(value.dtype)}
    if attrs.has(type(value)):
        return {f.name: summarize(getattr(value, f.name), depth + 1) for f in attrs.fields(type(value))}
    if isinstance(value, dict):
        return {str(k): summarize(v, depth + 1) for k, v in value.items()}
    if isinstance(value, list | tuple):
        if len(value) > MAX_INLINE_ELEMENTS and all(isinstance(v, int | float) for v in value):
            return {"length": len(value)}
        return [summarize(v, depth + 1) for v in value]
    fields = getattr(value, "get_fields_and_field_types", None)  # a ROS message used as a value
    if callable(fields):
        return {name: summarize(getattr(value, name), depth + 1) for name in fields()}
    return repr(value)[:200]
