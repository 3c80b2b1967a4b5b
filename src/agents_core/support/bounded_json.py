"""Bounded JSON decoding: a document from the network or a user costs O(its size), whatever it holds.

:func:`json.loads` trusts its input: 32 MB of ``{}`` becomes ~10 M dicts (a recipe went from 62 to
831 MB and spent 4.7 s), 100,000 nested brackets raise :class:`RecursionError`, ``10**400`` decodes
to an int that later overflows any float conversion, and ``NaN`` / ``Infinity`` pass. :func:`loads`
decodes under :class:`JsonLimits` instead, in two steps:

1. a **scan** that builds nothing: the size is checked first; strings are collapsed to ``0`` by
   regular expressions, 1,024 strings at a time (so brackets inside strings do not count, and a
   string too long or never closed is found); the brackets that remain are counted in
   C (``str.count``) and then walked one by one, without recursion, for the depth, the length of
   each array and object and the memory the decoded containers will take. The walk visits each
   bracket once and the counts are checked before it, so hostile input is refused after O(n) work
   in C and at most ``max_objects + max_arrays`` steps in Python;
2. :func:`json.loads`, only once the scan found nothing over a limit, with number hooks only when
   the scan saw a number that may be out of range (a long digit run or an exponent).

Every refusal is an :class:`InvalidJsonError` (a :class:`~agents_core.errors.TypeValidationError`,
so also a ``ValueError``); one over a limit is a :class:`JsonLimitError` whose ``limit`` names the
:class:`JsonLimits` field. This module imports only the standard library, attrs and
:mod:`agents_core.errors`, so the transports, the web UI and the CLI can all use it.
"""

from __future__ import annotations

import functools
import json
import math
import re
import sys
from typing import Any

from attrs import define, field

from ..errors import TypeValidationError

__all__ = ["DEFAULT_JSON_LIMITS", "REQUEST_JSON_LIMITS", "InvalidJsonError", "JsonLimitError", "JsonLimits", "loads"]

_KIB, _MIB = 1024, 1024 * 1024
# The memory of the decoded containers, as CPython builds them (sys.getsizeof, 3.11): an empty dict
# is 64 bytes, one with 1-5 keys 184, and each further key ~48; a list is 56 bytes plus a pointer per
# item. Charging 184 + 48 per entry overestimates small objects a little, never underestimates.
_OBJECT_BASE, _OBJECT_ITEM = 184, 48
_ARRAY_BASE, _ARRAY_ITEM = 56, 8
# Every document may use this much beyond max_expansion x its size, so small documents are never
# refused for the fixed cost of their few containers.
_BUDGET_SLACK = 256 * _KIB
# Possessive quantifiers (Python 3.11+) keep the regex engine from saving backtracking state per
# repetition: without them a string of 8 M escapes took ~1 GB to match (so it still does on 3.10).
_PLUS = "+" if sys.version_info >= (3, 11) else ""
# A JSON string: the quotes and everything between them, escapes (a backslash and the next
# character) included; the unrolled form is linear.
_STRING_BODY = rf'[^"\\]*{_PLUS}(?:\\.[^"\\]*{_PLUS})*{_PLUS}'
_STRING = re.compile(rf'"{_STRING_BODY}"', re.DOTALL)
_BRACKET = re.compile(r"[\[\]{}]")
# A number that may not fit: 20+ digits in a row (2**64 has 20) or an exponent. Only documents that
# have one are decoded with the (slower) number hooks.
_SUSPICIOUS_NUMBER = re.compile(r"\d{20}|\d[eE]")


class InvalidJsonError(TypeValidationError):
    """A JSON document from outside is not valid JSON (syntax, encoding) or exceeds its :class:`JsonLimits`."""


class JsonLimitError(InvalidJsonError):
    """A JSON document exceeds one of its :class:`JsonLimits`; ``limit`` names the field."""

    def __init__(self, message: str, *, limit: str) -> None:
        super().__init__(message)
        self.limit = limit


def _non_negative(instance: Any, attribute: Any, value: int) -> None:
    minimum = 1 if attribute.name in ("max_bytes", "max_depth", "max_expansion") else 0
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise JsonLimitError(f"JsonLimits.{attribute.name} must be an int >= {minimum}, got {value!r}",
                             limit=attribute.name)


@define(frozen=True)
class JsonLimits:
    """What decoding one JSON document may cost; :func:`loads` refuses one that exceeds any of them.

    - ``max_bytes``: the document's size (bytes, or characters for a ``str``), checked first.
    - ``max_depth``: how deeply arrays and objects may nest (the top-level container is depth 1).
    - ``max_objects``, ``max_arrays``: how many objects / arrays the whole document may hold.
    - ``max_object_len``, ``max_array_len``: the entries of any one object / items of any one array.
    - ``max_str_len``: the length of any one string, as written in the document (an escape such as
      ``\\n`` counts as one character or two, depending on the Python version).
    - ``max_expansion``: the memory of the decoded containers, estimated from their sizes before
      anything is built, may not exceed ``max_expansion`` x the document's size + 256 KiB.
    - ``min_int``, ``max_int``: the range of integers (default: what fits 64 bits, as in msgpack),
      so ``10**400`` is refused rather than overflowing whatever converts it later.
    - ``allow_non_finite``: whether ``NaN``, ``Infinity``, ``-Infinity`` and floats that overflow
      to infinity (``1e400``) are accepted; they are not valid JSON (RFC 8259) and are refused by default.

    A limit of 0 on a count or length forbids all but empty ones.
    """

    max_bytes: int = field(default=16 * _MIB, validator=_non_negative)
    max_depth: int = field(default=128, validator=_non_negative)
    max_objects: int = field(default=65_536, validator=_non_negative)
    max_arrays: int = field(default=262_144, validator=_non_negative)
    max_object_len: int = field(default=4096, validator=_non_negative)
    max_array_len: int = field(default=262_144, validator=_non_negative)
    max_str_len: int = field(default=16 * _MIB, validator=_non_negative)
    max_expansion: int = field(default=32, validator=_non_negative)
    min_int: int = -(2**63)
    max_int: int = 2**64 - 1
    allow_non_finite: bool = False


#: The limits of :func:`loads` called without any: a document a user or a web page sends.
DEFAULT_JSON_LIMITS = JsonLimits()
#: The limits of a JSON service / transition request from the network: the same sizes and counts as
#: the msgpack form of the request gets (``agents_zenoh.codecs.DEFAULT_DECODE_LIMITS``).
REQUEST_JSON_LIMITS = JsonLimits(max_bytes=64 * _MIB, max_str_len=64 * _MIB)


def loads(document: str | bytes | bytearray | memoryview, limits: JsonLimits | None = None) -> Any:
    """Decode a JSON ``document`` (``bytes`` must be UTF-8) under ``limits`` (default :data:`DEFAULT_JSON_LIMITS`).

    Raises :class:`JsonLimitError` naming the first limit exceeded, before building anything
    large, or :class:`InvalidJsonError` for a document that is not JSON.
    """
    limits = DEFAULT_JSON_LIMITS if limits is None else limits
    size = len(document) if isinstance(document, str) else memoryview(document).nbytes
    if size > limits.max_bytes:
        raise JsonLimitError(f"the JSON document has {size} bytes, more than {limits.max_bytes} "
                             "(JsonLimits.max_bytes)", limit="max_bytes")
    if isinstance(document, str):
        text = document
    else:
        try:
            text = str(document, "utf-8")
        except UnicodeDecodeError as exc:
            raise InvalidJsonError(f"the JSON document is not UTF-8 ({exc})") from None
    if not text or text.isspace():
        raise InvalidJsonError("the JSON document is empty")
    skeleton = _scan(text, size, limits)
    hooks: dict[str, Any] = {"parse_constant": _constant_hook(limits)}
    if _SUSPICIOUS_NUMBER.search(skeleton):
        hooks.update(parse_int=_int_hook(limits), parse_float=_float_hook(limits))
    try:
        return json.loads(text, **hooks)
    except RecursionError:
        # The scan bounds the depth; this is for a caller already deep in its own stack.
        raise JsonLimitError("the JSON document nests too deeply to decode here (JsonLimits.max_depth)",
                             limit="max_depth") from None
    except json.JSONDecodeError as exc:
        raise InvalidJsonError(f"invalid JSON: {exc}") from None


def _scan(text: str, size: int, limits: JsonLimits) -> str:
    """Check ``text`` against ``limits`` without decoding it; return its skeleton (strings as ``0``)."""
    skeleton = _collapse_strings(text, limits.max_str_len) if '"' in text else text
    for count, which, kind in ((skeleton.count("{"), "max_objects", "objects"),
                               (skeleton.count("["), "max_arrays", "arrays")):
        if count > getattr(limits, which):
            raise JsonLimitError(f"the JSON document holds {count} {kind}, more than {getattr(limits, which)} "
                                 f"(JsonLimits.{which})", limit=which)
    if skeleton.count("]") != skeleton.count("[") or skeleton.count("}") != skeleton.count("{"):
        # Checked here so that the walk below visits at most 2 x (max_objects + max_arrays) brackets.
        raise InvalidJsonError("invalid JSON: its brackets do not balance")
    if not limits.allow_non_finite and ("N" in skeleton or "I" in skeleton):
        # Outside strings, N and I only start NaN / Infinity (anything else is a syntax error anyway).
        raise JsonLimitError("the JSON document holds NaN or Infinity (JsonLimits.allow_non_finite)",
                             limit="allow_non_finite")
    _walk_brackets(skeleton, size, limits)
    return skeleton


def _collapse_strings(text: str, max_len: int) -> str:
    """``text`` with each string replaced by ``0``; refuses a string over ``max_len`` or one left open.

    ``re.sub`` over the whole text would keep a list entry (and often a new small ``str``) per
    string until it joins them, ~10x the document; here it runs on runs of up to 1,024 strings,
    matched one run at a time from outside any string, so the memory beyond the skeleton is small.
    """
    run = _string_run(max_len if max_len < len(text) else None)
    pieces: list[str] = []
    pos, end = 0, len(text)
    while pos < end:
        stop = run.match(text, pos).end()  # type: ignore[union-attr]  # the run may be empty, never absent
        if stop == pos:
            # Only a quote stops a run: one that opens a string too long or never closed.
            if max_len < len(text):
                raise JsonLimitError(f"the JSON document holds a string longer than {max_len} characters, "
                                     "or an unterminated one (JsonLimits.max_str_len)", limit="max_str_len")
            raise InvalidJsonError(f"invalid JSON: the string at offset {pos} is never closed")
        pieces.append(_STRING.sub("0", text[pos:stop]))
        pos = stop
    return "".join(pieces)


@functools.lru_cache(maxsize=8)
def _string_run(max_len: int | None) -> re.Pattern[str]:
    """Up to 1,024 whole strings and the text between them, from a position outside any string."""
    body = _STRING_BODY if max_len is None else rf'(?:[^"\\]|\\.){{0,{max_len}}}{_PLUS}'
    return re.compile(rf'(?:[^"]*{_PLUS}"{body}"){{0,1024}}{_PLUS}[^"]*{_PLUS}', re.DOTALL)


def _walk_brackets(skeleton: str, size: int, limits: JsonLimits) -> None:
    """Depth, container lengths and memory, visiting each bracket once (no recursion)."""
    # One [is_object, commas, non_empty] per open container; its length is commas + 1 when non-empty.
    stack: list[list[Any]] = []
    memory_left = limits.max_expansion * size + _BUDGET_SLACK
    prev = 0
    for match in _BRACKET.finditer(skeleton):
        pos = match.start()
        if stack and pos > prev:
            top = stack[-1]
            top[1] += skeleton.count(",", prev, pos)
            if not top[2] and not skeleton[prev:pos].isspace():
                top[2] = True
            _check_length(top, limits)
        prev = pos + 1
        char = skeleton[pos]
        if char in "[{":
            if stack:
                stack[-1][2] = True
            if len(stack) >= limits.max_depth:
                raise JsonLimitError(f"the JSON document nests deeper than {limits.max_depth} levels "
                                     "(JsonLimits.max_depth)", limit="max_depth")
            stack.append([char == "{", 0, False])
        elif not stack:
            raise InvalidJsonError(f"invalid JSON: {char!r} at offset {pos} closes nothing")
        else:
            is_object, commas, non_empty = stack.pop()
            items = commas + 1 if non_empty else 0
            memory_left -= (_OBJECT_BASE + _OBJECT_ITEM * items) if is_object else (_ARRAY_BASE + _ARRAY_ITEM * items)
            if memory_left < 0:
                raise JsonLimitError(f"the {size}-byte JSON document expands to more than {limits.max_expansion}x "
                                     "its size in memory (JsonLimits.max_expansion)", limit="max_expansion")


def _check_length(top: list[Any], limits: JsonLimits) -> None:
    is_object, commas, _ = top
    which = "max_object_len" if is_object else "max_array_len"
    if commas + 1 > getattr(limits, which):
        kind = "an object with more than {} entries" if is_object else "an array with more than {} items"
        raise JsonLimitError(f"the JSON document holds {kind.format(getattr(limits, which))} (JsonLimits.{which})",
                             limit=which)


def _int_hook(limits: JsonLimits) -> Any:
    # Digits first: int() of thousands of digits is quadratic, and 2**64 has 20.
    longest = max(len(str(limits.min_int)), len(str(limits.max_int)))

    def parse_int(digits: str) -> int:
        value = int(digits) if len(digits) <= longest else None
        if value is None or not limits.min_int <= value <= limits.max_int:
            shown = digits if len(digits) <= 24 else f"{digits[:12]}...({len(digits)} digits)"
            bits = ", which does not fit 64 bits" if (limits.min_int, limits.max_int) == (-(2**63), 2**64 - 1) else ""
            raise JsonLimitError(f"the JSON document holds the integer {shown}{bits}, outside "
                                 f"[{limits.min_int}, {limits.max_int}] (JsonLimits.min_int / max_int)",
                                 limit="max_int")
        return value

    return parse_int


def _float_hook(limits: JsonLimits) -> Any:
    def parse_float(text: str) -> float:
        value = float(text)
        if not limits.allow_non_finite and not math.isfinite(value):
            shown = text if len(text) <= 24 else f"{text[:12]}...({len(text)} characters)"
            raise JsonLimitError(f"the JSON number {shown} overflows a float (JsonLimits.allow_non_finite)",
                                 limit="allow_non_finite")
        return value

    return parse_float


def _constant_hook(limits: JsonLimits) -> Any:
    def parse_constant(name: str) -> float:
        if not limits.allow_non_finite:
            raise JsonLimitError(f"the JSON document holds {name} (JsonLimits.allow_non_finite)",
                                 limit="allow_non_finite")
        return float(name)

    return parse_constant
