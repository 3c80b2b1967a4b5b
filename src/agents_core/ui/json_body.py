"""``parse_json_body``: JSON from the network, bounded in size, nesting depth, elements and numbers.

``json.loads`` alone turns 100,000 nested brackets into a RecursionError, ``10**400`` into an
integer that overflows every float conversion after it, and a megabyte of ``[]`` into a million
lists. Here the nesting depth and the number of containers and items are counted on the raw
bytes first (strings blanked out with one regular expression, then a vectorised running sum),
so a hostile document is refused before a single Python object is built for it; numbers are
refused while parsing when they do not fit a 64-bit integer or a finite float.

(The core is getting a bounded JSON decoder of its own for every transport; this is the UI's
guard until the two are unified.)
"""

from __future__ import annotations

import json
import re
from typing import Any

import numpy as np

__all__ = ["MAX_DEPTH", "MAX_ITEMS", "BadJSON", "parse_json_body"]

#: The deepest nesting of arrays / objects accepted.
MAX_DEPTH = 32
#: The most values (containers, items and keys together, counted by their separators) accepted.
MAX_ITEMS = 1_000_000
#: Integers past this magnitude (64 bits) have no topic type that could hold them.
_MAX_INT = 2**64
_MAX_INT_DIGITS = 21

# An unterminated string runs to the end (rather than failing and being retried from every later
# quote, which would be quadratic); the document is then refused by the parser.
_STRING = re.compile(rb'"(?:[^"\\]|\\.)*(?:"|\\?\Z)', re.DOTALL)


class BadJSON(ValueError):
    """A body that is not JSON, or JSON past the bounds; ``str()`` says which."""


def _check_shape(body: bytes, max_depth: int, max_items: int) -> None:
    bare = np.frombuffer(_STRING.sub(b'""', body), dtype=np.uint8)
    opens = (bare == ord("[")) | (bare == ord("{"))
    closes = (bare == ord("]")) | (bare == ord("}"))
    if opens.any():
        depth = int(np.cumsum(opens.astype(np.int32) - closes.astype(np.int32)).max())
        if depth > max_depth:
            raise BadJSON(f"the JSON is nested {depth} deep; at most {max_depth}")
    items = int(opens.sum()) + int((bare == ord(",")).sum())
    if items > max_items:
        raise BadJSON(f"the JSON has about {items} values; at most {max_items}")


def _bounded_int(text: str) -> int:
    digits = text.lstrip("-")
    if len(digits) > _MAX_INT_DIGITS or abs(int(text)) >= _MAX_INT:
        raise BadJSON(f"the integer {text[:24]}{'...' if len(text) > 24 else ''} does not fit 64 bits")
    return int(text)


def _finite_float(text: str) -> float:
    value = float(text)
    if value in (float("inf"), float("-inf")):
        raise BadJSON(f"the number {text[:24]} is out of the range of a float")
    return value


def _no_constant(name: str) -> Any:
    raise BadJSON(f"{name} is not a JSON number")


def parse_json_body(body: bytes, *, max_bytes: int, max_depth: int = MAX_DEPTH, max_items: int = MAX_ITEMS) -> Any:
    """The JSON document in ``body``, or :class:`BadJSON` naming what is wrong or past the bounds."""
    if len(body) > max_bytes:
        raise BadJSON(f"the JSON body is {len(body)} bytes; at most {max_bytes}")
    _check_shape(body, max_depth, max_items)
    try:
        return json.loads(body, parse_int=_bounded_int, parse_float=_finite_float, parse_constant=_no_constant)
    except BadJSON:
        raise
    except (ValueError, RecursionError) as exc:  # JSONDecodeError, UnicodeDecodeError are ValueErrors
        raise BadJSON(f"the body is not JSON ({exc})") from None
