"""agents_core.support.bounded_json: hostile JSON is refused by a scan that builds nothing; valid JSON decodes as usual.

Each hostile shape below took unbounded memory or time, or raised something other than a clear
error, under a plain ``json.loads`` (32 MB of ``{}``: ~870 MB peak; 100,000 nested brackets:
RecursionError; ``10**400``: an int that overflows later; ``NaN``: accepted). Here each ends in a
:class:`JsonLimitError` naming the limit, with a traced peak within a small multiple of its size.
"""

from __future__ import annotations

import json
import math
import tracemalloc
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from agents_core.errors import ConfigError, TypeValidationError
from agents_core.support.bounded_json import (
    DEFAULT_JSON_LIMITS,
    REQUEST_JSON_LIMITS,
    InvalidJsonError,
    JsonLimitError,
    JsonLimits,
    loads,
)

_MIB = 1024 * 1024


def _objects_flood(size: int) -> str:
    return "[" + ",".join(["{}"] * (size // 3)) + "]"


# (shape, document, the JsonLimits field that refuses it); sizes are what the probes sent.
HOSTILE: list[tuple[str, str, str]] = [
    ("huge document", "[" + "1," * (21 * _MIB) + "1]", "max_bytes"),
    ("many small objects", _objects_flood(32 * _MIB), "max_objects"),
    ("many small arrays", "[" + ",".join(["[]"] * 300_000) + "]", "max_arrays"),
    ("deep nesting", "[" * 100_000 + "]" * 100_000, "max_depth"),
    ("deep objects", '{"a":' * 1000 + "0" + "}" * 1000, "max_depth"),
    ("long array", "[" + "0," * 300_000 + "0]", "max_array_len"),
    ("wide object", "{" + ",".join(f'"k{i}":0' for i in range(5000)) + "}", "max_object_len"),
    ("huge string", '["' + "a" * (2 * _MIB) + '"]', "max_str_len"),
    ("huge int", "[" + "9" * 5000 + "]", "max_int"),
    ("10**400", json.dumps({"x": 10**400}), "max_int"),
    ("negative huge int", "[-" + "9" * 30 + "]", "max_int"),
    ("float overflow", "[1e400]", "allow_non_finite"),
    ("float overflow by digits", "[" + "9" * 400 + ".0]", "allow_non_finite"),
    ("NaN", '{"a": NaN}', "allow_non_finite"),
    ("Infinity", "[-Infinity]", "allow_non_finite"),
    ("memory expansion", "[" + ",".join(['{"a":0}'] * 60_000) + "]", "max_expansion"),
]
# The limits of the table: the request limits with a smaller document, string and object budget,
# so that every shape above meets its own limit first.
TABLE_LIMITS = JsonLimits(max_bytes=40 * _MIB, max_str_len=1 * _MIB, max_expansion=8)


@pytest.mark.parametrize(("shape", "document", "limit"), HOSTILE, ids=[h[0] for h in HOSTILE])
@pytest.mark.parametrize("as_bytes", [False, True], ids=["str", "bytes"])
def test_hostile_documents_are_refused_naming_the_limit_within_a_small_multiple_of_their_size(
        shape: str, document: str, limit: str, as_bytes: bool) -> None:
    payload: str | bytes = document.encode() if as_bytes else document
    tracemalloc.start()
    try:
        with pytest.raises(JsonLimitError) as caught:
            loads(payload, TABLE_LIMITS)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert caught.value.limit == limit, caught.value
    assert f"JsonLimits.{limit}" in str(caught.value) or (limit == "max_int" and "max_int" in str(caught.value))
    # The decoded text and its skeleton (strings collapsed) are the only copies; nothing is built.
    assert peak <= 3 * len(document) + 1 * _MIB, f"{shape}: peak {peak} for {len(document)} bytes"


def test_plain_json_loads_is_what_the_table_guards_against() -> None:
    # The same shapes, decoded by json.loads: an error nobody handles, or a value that costs ~30x its size.
    with pytest.raises(RecursionError):
        json.loads("[" * 100_000 + "]" * 100_000)
    assert math.isnan(json.loads('{"a": NaN}')["a"])
    with pytest.raises(OverflowError):
        float(json.loads(json.dumps(10**400)))


@pytest.mark.parametrize("document", [
    "", "   ", "{", '{"a": 1', '{"a": "b', "]", "][", "[1 2]", '{"a" 1}', "nul", '["\\x"]', "[1,]",
    '"\\ud800"x', b"\xff\xfe[]", b'["\xc3"]',
])
def test_malformed_documents_are_invalid_json_errors(document: str | bytes) -> None:
    with pytest.raises(InvalidJsonError) as caught:
        loads(document)
    assert isinstance(caught.value, TypeValidationError) and isinstance(caught.value, ValueError)


def test_the_error_types_sit_in_the_framework_tree() -> None:
    assert issubclass(JsonLimitError, InvalidJsonError)
    assert issubclass(InvalidJsonError, TypeValidationError)
    assert issubclass(InvalidJsonError, ValueError)


@pytest.mark.parametrize("document", [
    '{"a": "]]]]{{{{", "b": "\\"[", "c": ["\\\\", "x\\\\\\"]"]}',
    '[{"k": [1, 2.5, -3e-5, true, false, null, "s"]}, [], {}, [[[]]], ""]',
    '  {"nested": {"deeper": {"deepest": [1, {"x": "y"}]}}}  ',
    json.dumps({"max64": 2**64 - 1, "min64": -(2**63), "f": 1.7976931348623157e308, "tiny": 5e-324}),
    json.dumps(["ünïcödé", "𝄞", "\u2028", "\x00"]),
    "0", '"just a string"', "null",
])
def test_valid_documents_decode_as_json_loads_does(document: str) -> None:
    assert loads(document) == json.loads(document)
    assert loads(document.encode()) == json.loads(document)


def test_limits_at_their_edge_accept_and_one_past_refuse() -> None:
    limits = JsonLimits(max_depth=3, max_array_len=3, max_object_len=2, max_arrays=4, max_objects=2, max_str_len=4)
    assert loads("[[[1, 2, 3]]]", limits) == [[[1, 2, 3]]]
    assert loads('{"a": {"b": "abcd"}, "c": 0}', limits) == {"a": {"b": "abcd"}, "c": 0}
    assert loads("[[], [], []]", limits) == [[], [], []]
    for document, limit in (("[[[[]]]]", "max_depth"), ("[1, 2, 3, 4]", "max_array_len"),
                            ('{"a": 1, "b": 2, "c": 3}', "max_object_len"), ("[[], [], [], []]", "max_arrays"),
                            ("[{}, {}, {}]", "max_objects"), ('["abcde"]', "max_str_len")):
        with pytest.raises(JsonLimitError) as caught:
            loads(document, limits)
        assert caught.value.limit == limit, (document, caught.value)


def test_non_finite_numbers_and_big_ints_are_a_policy() -> None:
    lenient = JsonLimits(allow_non_finite=True, min_int=-(10**500), max_int=10**500)
    doc = loads("[NaN, Infinity, -Infinity, 1e400, " + str(10**400) + "]", lenient)
    assert math.isnan(doc[0]) and doc[1:4] == [math.inf, -math.inf, math.inf] and doc[4] == 10**400
    assert loads("[1e5, 12345678901234567890]") == [1e5, 12345678901234567890]
    with pytest.raises(JsonLimitError, match="max_int"):
        loads("[18446744073709551616]")  # 2**64


@pytest.mark.parametrize("field", ["max_bytes", "max_depth", "max_objects", "max_array_len", "max_expansion"])
def test_limits_are_validated(field: str) -> None:
    for bad in (-1, True, 1.5):
        kwargs: dict[str, Any] = {field: bad}
        with pytest.raises(ConfigError, match=field):
            JsonLimits(**kwargs)


def test_the_request_limits_are_the_default_ones_with_a_larger_document() -> None:
    assert REQUEST_JSON_LIMITS.max_bytes == REQUEST_JSON_LIMITS.max_str_len == 64 * _MIB
    assert REQUEST_JSON_LIMITS.max_depth == DEFAULT_JSON_LIMITS.max_depth


def test_a_document_at_the_nesting_limit_decodes_even_from_deep_in_the_stack() -> None:
    document = "[" * DEFAULT_JSON_LIMITS.max_depth + "]" * DEFAULT_JSON_LIMITS.max_depth

    def deep(n: int) -> Any:
        return loads(document) if n == 0 else deep(n - 1)

    assert deep(300) is not None


_JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(min_value=-(2**63), max_value=2**64 - 1)
    | st.floats(allow_nan=False, allow_infinity=False) | st.text(),
    lambda inner: st.lists(inner, max_size=6) | st.dictionaries(st.text(), inner, max_size=6),
    max_leaves=40,
)


@settings(derandomize=True, database=None, max_examples=300, deadline=None)
@given(_JSON_VALUES, st.booleans())
def test_any_json_value_within_the_limits_round_trips(value: Any, ascii_only: bool) -> None:
    text = json.dumps(value, ensure_ascii=ascii_only)
    assert loads(text) == json.loads(text)
    assert loads(text.encode()) == json.loads(text)
