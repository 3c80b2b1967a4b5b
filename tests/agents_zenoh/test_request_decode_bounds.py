"""A hostile request is refused the same way whatever its encoding: one table, encodings x hostile shapes.

A raw Zenoh session (the attacker: no project code on its side) sends each shape, as msgpack and as
JSON, to a service (``relay/execute_method``) and to the transition queryable of a component of the
recipe subprocess (``tests/agents_zenoh/recipe.py``, a real ``Launcher(transport="zenoh")``). Each
must end in a ``CodecError`` error reply in the request's own encoding that names the limit; the
component's request lane must answer a normal request right after; and the recipe's peak RSS
(``VmHWM``, reset before each case through ``/proc/<pid>/clear_refs``) may grow by at most a small
multiple of the payload. Before JSON requests were bounded, 32 MB of ``{}`` took the recipe's peak
from 52 to 919 MB and 100,000 nested brackets answered ``RecursionError``.
Times are printed (``-s``) for the record; none is asserted.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh")
pytest.importorskip("msgpack")

import msgpack
import zenoh

from agents_core.support.bounded_json import REQUEST_JSON_LIMITS
from agents_zenoh.codecs import DEFAULT_DECODE_LIMITS
from agents_zenoh.codecs.limits import json_limits
from tests.agents_zenoh import raw_client as rc
from tests.agents_zenoh.test_multiprocess import Recipe, running_recipe

pytestmark = pytest.mark.zenoh

_MIB = 1024 * 1024
JSON, MSGPACK = "application/json", "application/msgpack"
NORMAL = {"method": "input_statistics"}


def _json(text: str) -> bytes:
    return text.encode()


def _request_with(args_json: str) -> bytes:
    return _json('{"method": "input_statistics", "args": ' + args_json + "}")


# shape -> {encoding: (payload builder, what the error names)}; an encoding missing from a row
# cannot express the shape (msgpack has no integer beyond 64 bits; NaN is a valid msgpack float,
# which topics such as LaserScan carry, so a msgpack request with one reaches its handler).
SHAPES: dict[str, dict[str, tuple[Any, str]]] = {
    "huge document": {
        JSON: (lambda: _request_with("[" + "1," * (33 * _MIB) + "1]"), "max_document_bytes"),
        MSGPACK: (lambda: msgpack.packb({"method": "input_statistics", "args": [b"x" * (65 * _MIB)]}),
                  "max_document_bytes"),
    },
    "many small objects (32 MB of {})": {
        JSON: (lambda: _request_with("[" + ",".join(["{}"] * (32 * _MIB // 3)) + "]"), "JsonLimits.max_objects"),
        MSGPACK: (lambda: msgpack.packb({"method": "x", "args": [[{}] * 262_144] * 128}), "DecodeLimits.max_maps"),
    },
    "many small arrays": {
        JSON: (lambda: _request_with("[" + ",".join(["[]"] * 300_000) + "]"), "JsonLimits.max_arrays"),
        # one byte per empty array on the wire: the memory budget is met before the count
        MSGPACK: (lambda: msgpack.packb({"method": "x", "args": [[[]] * 150_000] * 2}), "DecodeLimits.max_expansion"),
    },
    "deep nesting (100k brackets)": {
        JSON: (lambda: _request_with("[" * 100_000 + "]" * 100_000), "JsonLimits.max_depth"),
        MSGPACK: (lambda: b"\x81\xa4args" + b"\x91" * 100_000 + b"\x90", "StackError"),
    },
    "long array": {
        JSON: (lambda: _request_with("[" + "0," * 300_000 + "0]"), "JsonLimits.max_array_len"),
        MSGPACK: (lambda: msgpack.packb({"method": "x", "args": [0] * 300_000}), "max_array_len"),
    },
    "huge string": {
        JSON: (lambda: _request_with('["' + "a" * (65 * _MIB) + '"]'), "max_document_bytes"),
        MSGPACK: (lambda: msgpack.packb({"method": "a" * (65 * _MIB)}), "max_document_bytes"),
    },
    "huge int (10**400)": {
        JSON: (lambda: _request_with(json.dumps([10**400])), "JsonLimits.min_int / max_int"),
    },
    "NaN": {
        JSON: (lambda: _request_with("[NaN]"), "JsonLimits.allow_non_finite"),
    },
    "wrong top-level type": {
        JSON: (lambda: _json(json.dumps([1, 2])), "a request must be a map, got list"),
        MSGPACK: (lambda: msgpack.packb([1, 2]), "a request must be a map, got list"),
    },
    "truncated": {
        JSON: (lambda: _json(json.dumps(NORMAL))[:-5], "invalid JSON"),
        MSGPACK: (lambda: msgpack.packb(NORMAL)[:-5], "ends inside"),
    },
}
# Shapes of 64 MiB and more take seconds to build and send: run with the slow tests.
_SLOW = {"huge document", "huge string"}
CASES = [pytest.param(shape, encoding, target, id=f"{shape}-{encoding.split('/')[1]}-{target}",
                      marks=[pytest.mark.slow] if shape in _SLOW else [])
         for shape, row in SHAPES.items() for encoding in (MSGPACK, JSON) if encoding in row
         for target in ("service", "transition")]


def _memory_mb(pid: int) -> dict[str, float]:
    fields = {}
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        name, _, value = line.partition(":")
        if name in ("VmRSS", "VmHWM"):
            fields[name] = int(value.split()[0]) / 1024
    return fields


def _reset_peak(pid: int) -> bool:
    """Reset the process's peak RSS (VmHWM) to its current RSS; False where the kernel does not allow it."""
    try:
        Path(f"/proc/{pid}/clear_refs").write_text("5")
    except OSError:
        return False
    return True


def _ask(session: zenoh.Session, key: str, payload: bytes, encoding: str) -> tuple[float, bool, str, Any]:
    """(seconds, ok, reply encoding, decoded reply) of one query."""
    start = time.monotonic()
    replies = list(session.get(key, payload=payload, encoding=encoding, timeout=30.0))
    elapsed = time.monotonic() - start
    assert len(replies) == 1, f"{len(replies)} replies from {key}"
    ok, err = replies[0].ok, replies[0].err
    sample: Any = ok if ok is not None else err
    raw = sample.payload.to_bytes()
    reply_encoding = str(sample.encoding)
    body = json.loads(raw) if reply_encoding.startswith(JSON) else msgpack.unpackb(raw)
    return elapsed, ok is not None, reply_encoding, body


@pytest.fixture(scope="module")
def recipe(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Recipe, zenoh.Session]]:
    with running_recipe(tmp_path_factory.mktemp("request_bounds")) as pair:
        yield pair


def _encode(encoding: str, document: dict[str, Any]) -> bytes:
    return _json(json.dumps(document)) if encoding == JSON else msgpack.packb(document)


@pytest.mark.parametrize(("shape", "encoding", "target"), CASES)
def test_a_hostile_request_is_refused_cheaply_and_the_lane_answers_right_after(
        recipe: tuple[Recipe, zenoh.Session], shape: str, encoding: str, target: str) -> None:
    process, session = recipe
    build, names = SHAPES[shape][encoding]
    payload = build()
    size_mb = len(payload) / _MIB
    key = rc.key(process.namespace, "relay/execute_method" if target == "service" else "@agents/transition/relay")
    pid = process.proc.pid
    can_reset = _reset_peak(pid)
    before = _memory_mb(pid)
    elapsed, ok, reply_encoding, body = _ask(session, key, payload, encoding)
    after = _memory_mb(pid)
    del payload
    growth = after["VmHWM"] - before["VmRSS"]
    print(f"\n{shape} as {encoding} to the {target}: {size_mb:.1f} MB answered in {elapsed:.3f} s; "
          f"peak RSS +{growth:.0f} MB ({before['VmRSS']:.0f} -> peak {after['VmHWM']:.0f} MB)"
          f"{'' if can_reset else ' (peak not reset)'}; reply: {str(body)[:100]}")
    if can_reset:
        # Zenoh's receive buffer and the copy out of it, the decoded text and its skeleton: a few
        # copies of the payload at most (unbounded, 32 MB of {} peaked at +867 MB).
        assert growth <= 4 * size_mb + 64, f"{shape}: the recipe's peak RSS grew by {growth:.0f} MB"

    assert not ok, f"{shape} was accepted: {body}"
    assert reply_encoding == f"{encoding};error"
    assert body["type"] == "CodecError", body
    assert names in body["error"], body["error"]
    # The lane that decoded it is free again: a normal request on the same queryable is answered.
    normal = NORMAL if target == "service" else {"transition": "no_such_transition"}
    normal_elapsed, normal_ok, _, normal_body = _ask(session, key, _encode(encoding, normal), encoding)
    if target == "service":
        assert normal_ok and set(normal_body["result"]) >= {"delivered", "decode_errors"}, normal_body
    else:  # an unknown transition is answered (not applied): the handler ran
        assert normal_ok and normal_body == {"ok": False}, normal_body
    print(f"a normal request then took {normal_elapsed:.3f} s: {str(normal_body)[:80]}")


def test_json_requests_get_the_limits_of_their_msgpack_form() -> None:
    assert json_limits(DEFAULT_DECODE_LIMITS) == REQUEST_JSON_LIMITS
    assert REQUEST_JSON_LIMITS.max_objects == DEFAULT_DECODE_LIMITS.max_maps
    assert REQUEST_JSON_LIMITS.max_array_len == DEFAULT_DECODE_LIMITS.max_array_len
