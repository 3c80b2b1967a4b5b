"""Values on the command line: parsing what ``topics pub`` sends, summarising what ``topics echo`` shows.

Large arrays and byte strings (images, audio, point clouds) are never printed: they become
``{"shape": [...], "dtype": "..."}`` or ``{"bytes": n}``, so an echo of a camera topic stays
readable. Everything else is turned into JSON-ready data field by field.
"""

from __future__ import annotations

import enum
import json
import math
from typing import Any

import attrs
import numpy as np

from ..errors import ConfigError
from ..types.base import SupportedType

__all__ = ["parse_call_argument", "parse_value", "summarize"]

#: Arrays with more elements than this are shown as shape and dtype only.
MAX_INLINE_ELEMENTS = 16
#: Strings longer than this are cut (with their length shown).
MAX_INLINE_TEXT = 2000
_MAX_DEPTH = 8


def parse_call_argument(text: str) -> Any:
    """A JSON literal (``3``, ``true``, ``[1, 2]``, ``{"a": 1}``), else the text itself as a string."""
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def parse_value(msg_type: type[SupportedType], text: str) -> Any:
    """The value of ``msg_type`` that ``text`` (JSON, or a bare string) describes; ConfigError if none."""
    name = msg_type.type_name()
    raw = parse_call_argument(text)
    message_class = msg_type.message_class()
    candidates: list[Any] = [raw]
    if isinstance(raw, dict) and message_class is not object:
        try:
            candidates.insert(0, message_class(**raw))
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"value {text!r} does not fit {name}: {exc}") from None
    if not isinstance(raw, str):
        candidates.append(text)  # e.g. a String topic given "42"
    errors: list[Exception] = []
    for candidate in candidates:
        try:
            return msg_type.validate(candidate)
        except (TypeError, ValueError) as exc:
            errors.append(exc)
    # The reason for the text's own reading (the number "1e39": out of float32's range), not for
    # the last fallback tried (the string "1e39": not a number).
    raise ConfigError(f"value {text!r} does not fit {name}: {errors[0]}")


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
