"""Values on the command line: parsing what ``topics pub`` and ``call`` send, summarising what ``topics echo`` shows
(:mod:`agents_core.types.summary`).

Large arrays and byte strings (images, audio, point clouds) are never printed: they become
``{"shape": [...], "dtype": "..."}`` or ``{"bytes": n}``, so an echo of a camera topic stays
readable. Everything else is turned into JSON-ready data field by field.

Arguments are parsed as JSON under bounds checked before decoding (length, nesting depth) and
while decoding (no integer beyond 64 bits, no float that overflows to infinity), so that a
mistyped or hostile argument ends in a one-line :class:`ArgumentError`, never a RecursionError
or OverflowError traceback.
"""

from __future__ import annotations

import json
import math
import re
from typing import Any

from ..errors import ConfigError
from ..types.base import SupportedType
from ..types.summary import MAX_INLINE_ELEMENTS, MAX_INLINE_TEXT, summarize

__all__ = ["MAX_ARGUMENT_CHARS", "MAX_INLINE_ELEMENTS", "MAX_INLINE_TEXT", "MAX_JSON_DEPTH", "ArgumentError",
           "parse_call_argument", "parse_json_argument", "parse_value", "summarize"]

#: The longest argument (JSON or text) accepted, in characters.
MAX_ARGUMENT_CHARS = 1_000_000
#: The deepest nesting of JSON arrays and objects accepted in an argument.
MAX_JSON_DEPTH = 100
# What msgpack (the Zenoh wire format) and ROS integers can carry.
_INT_RANGE = (-(2**63), 2**64 - 1)
# A JSON string (an unterminated one runs to the end, so that the scan stays linear) or a bracket.
_STRING_OR_BRACKET = re.compile(r'"(?:[^"\\]+|\\.)*"?|[\[\]{}]', re.DOTALL)


class ArgumentError(ConfigError):
    """A command-line argument's value cannot be used (too long, too deep, out of range); exit status 2.

    The message is ``"<what> <reason>"``, e.g. ``--kwargs is not valid JSON: ...``; ``reason`` is kept.
    """

    def __init__(self, what: str, reason: str) -> None:
        super().__init__(f"{what} {reason}")
        self.what = what
        self.reason = reason


def _shorten(text: str, limit: int = 80) -> str:
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} chars)"


def _json_depth(text: str) -> int:
    """How deeply arrays and objects nest in ``text`` (strings skipped), without decoding it."""
    depth = deepest = 0
    for token in _STRING_OR_BRACKET.findall(text):
        if token in ("[", "{"):
            depth += 1
            deepest = max(deepest, depth)
        elif token in ("]", "}"):
            depth -= 1
    return deepest


def parse_json_argument(text: str, what: str) -> Any:
    """``text`` decoded as JSON; :class:`ArgumentError` naming ``what`` if it is out of bounds.

    Raises :class:`json.JSONDecodeError` when ``text`` is not JSON at all (callers may then take
    it as a string).
    """
    if len(text) > MAX_ARGUMENT_CHARS:
        raise ArgumentError(what, f"is {len(text)} characters long; at most {MAX_ARGUMENT_CHARS} are accepted")
    if text.lstrip()[:1] in ("[", "{") and (depth := _json_depth(text)) > MAX_JSON_DEPTH:
        raise ArgumentError(what, f"nests arrays/objects {depth} levels deep; at most {MAX_JSON_DEPTH} are accepted")

    def integer(digits: str) -> int:
        # Checked on the digits: int() of thousands of digits is slow, and refused beyond 4300.
        if len(digits.lstrip("-")) > 20 or not _INT_RANGE[0] <= (value := int(digits)) <= _INT_RANGE[1]:
            raise ArgumentError(what, f"holds the integer {_shorten(digits)}, which does not fit in 64 bits")
        return value

    def real(digits: str) -> float:
        value = float(digits)
        if math.isinf(value):
            raise ArgumentError(what, f"holds the number {_shorten(digits)}, which is too large for a float")
        return value

    try:
        return json.loads(text, parse_int=integer, parse_float=real)
    except RecursionError:  # the depth check above makes this unreachable; kept as a backstop
        raise ArgumentError(what, "nests arrays/objects too deeply") from None


def parse_call_argument(text: str, what: str = "argument") -> Any:
    """A JSON literal (``3``, ``true``, ``[1, 2]``, ``{"a": 1}``), else the text itself as a string.

    :class:`ArgumentError` (naming ``what``) for JSON out of bounds: see :func:`parse_json_argument`.
    """
    try:
        return parse_json_argument(text, what)
    except json.JSONDecodeError:
        return text


def parse_value(msg_type: type[SupportedType], text: str) -> Any:
    """The value of ``msg_type`` that ``text`` (JSON, or a bare string) describes; ConfigError if none."""
    name = msg_type.type_name()
    shown = _shorten(text)
    candidates: list[Any] = []
    refused: ArgumentError | None = None
    try:
        raw = parse_call_argument(text, "value")
    except ArgumentError as exc:
        refused = exc  # JSON out of bounds: the text may still be the value (e.g. of a String topic)
    else:
        candidates.append(raw)
        message_class = msg_type.message_class()
        if isinstance(raw, dict) and message_class is not object:
            try:
                candidates.insert(0, message_class(**raw))
            except (TypeError, ValueError, OverflowError) as exc:
                raise ArgumentError(f"value {shown!r}", f"does not fit {name}: {exc}") from None
    if not candidates or not isinstance(candidates[-1], str):
        candidates.append(text)  # e.g. a String topic given "42"
    first: Exception | None = None
    for candidate in candidates:
        try:
            return msg_type.validate(candidate)
        except (TypeError, ValueError, OverflowError) as exc:
            first = first or exc
    # The first candidate is the most specific reading of the text: its error says the most.
    raise ArgumentError(f"value {shown!r}", f"does not fit {name}: {f'it {refused.reason}' if refused else first}")
