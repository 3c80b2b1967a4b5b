"""``parse_json_body``: a request body from the browser, decoded with the core's bounded JSON decoder.

The UI has no JSON rules of its own: :func:`agents_core.support.bounded_json.loads` refuses deep nesting,
integers past 64 bits, floats that overflow, ``NaN`` and documents that would expand far beyond
their size, before building anything large. Only the UI's bounds differ from the decoder's
defaults (a body is at most ``max_bytes``; arrays may be as long as a body can make them, since an
input topic can take a long array of numbers), and its refusals are :class:`BadJSON`, which the
endpoints turn into a 400 that names the input.
"""

from __future__ import annotations

from typing import Any

from ..support.bounded_json import InvalidJsonError, JsonLimits, loads

__all__ = ["MAX_DEPTH", "BadJSON", "parse_json_body"]

#: The deepest nesting of arrays / objects accepted in a request body.
MAX_DEPTH = 32


class BadJSON(ValueError):
    """A body that is not JSON, or JSON past the bounds; ``str()`` says which."""


def parse_json_body(body: bytes, *, max_bytes: int, max_depth: int = MAX_DEPTH) -> Any:
    """The JSON document in ``body``, or :class:`BadJSON` naming what is wrong or past the bounds."""
    limits = JsonLimits(max_bytes=max_bytes, max_depth=max_depth, max_array_len=max_bytes, max_str_len=max_bytes)
    try:
        return loads(body, limits)
    except InvalidJsonError as exc:
        raise BadJSON(str(exc)) from None
