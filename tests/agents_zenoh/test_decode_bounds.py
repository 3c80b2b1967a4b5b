"""Bounded decoding of untrusted Zenoh payloads: anything a peer sends decodes or raises CodecError, cheaply.

Property-based (Hypothesis, derandomized so CI runs the same examples every time) over every
built-in type's codec: random bytes, random msgpack documents, valid payloads mutated (bit flips,
truncation, spliced bytes) and amplification documents (floods of empty lists and maps, short
strings, ...) scaled up to tens of thousands of items. Each payload's peak traced memory
(tracemalloc) must stay within ``BOUND_FACTOR`` x its size + ``BOUND_SLACK``: the decode limits
charge containers at most 32x their document's size (see ``DecodeLimits``); what they do not
count (short strings, preallocated list slots) measured below 20x; so 40x leaves headroom without
letting the ~70x of unbounded decoding through. Then the same on a real Zenoh session: a hostile
payload is rejected, counted, fast, and another topic keeps flowing.
"""

from __future__ import annotations

import itertools
import json
import threading
import time
import tracemalloc
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

pytest.importorskip("msgpack")
pytest.importorskip("zenoh")
pytest.importorskip("hypothesis")

import msgpack
import zenoh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from agents_core.messages import DetectionsMsg, ImageMsg, values_equal
from agents_core.supported_types import SupportedType, get_type, registered_types
from agents_core.topics import QoSConfig, Topic
from agents_core.types import is_builtin_type
from agents_zenoh.codecs import (
    DEFAULT_DECODE_LIMITS,
    CodecError,
    DecodeLimits,
    decode_limits,
    decode_value,
    describe_schemas,
    encode_value,
    register_codec,
    set_decode_limits,
    unpack,
)
from agents_zenoh.transport import ZenohTransport
from tests.conftest import free_tcp_port, wait_for

pytestmark = pytest.mark.zenoh

#: Peak traced memory of one decode <= BOUND_FACTOR x payload size + BOUND_SLACK (see the module docstring).
BOUND_FACTOR = 40
BOUND_SLACK = 2 * 1024 * 1024

_PROFILE = settings(deadline=None, derandomize=True, database=None, print_blob=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def _builtin_types() -> dict[str, type[SupportedType]]:
    # Other tests register types of their own in the process-wide registry; these have codecs.
    schemas = describe_schemas()
    return {n: t for n, t in registered_types().items()
            if is_builtin_type(t) and n in schemas}


TYPES = _builtin_types()
TYPE_NAMES = sorted(TYPES)


def _decode_within_bounds(type_name: str, payload: bytes) -> tuple[str, int]:
    """Decode ``payload`` as ``type_name``: ("ok" | "CodecError", peak traced bytes); any other exception fails."""
    tracemalloc.start()
    try:
        try:
            decode_value(TYPES[type_name], payload)
            outcome = "ok"
        except CodecError:
            outcome = "CodecError"
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    bound = BOUND_FACTOR * len(payload) + BOUND_SLACK
    assert peak <= bound, f"{type_name}: a {len(payload)}-byte payload peaked at {peak} traced bytes (> {bound})"
    return outcome, peak


# -- strategies ---------------------------------------------------------------------------------

_scalars = (st.none() | st.booleans() | st.integers(-(2**63), 2**64 - 1) | st.floats()
            | st.text(max_size=16) | st.binary(max_size=32))
_documents = st.recursive(
    _scalars,
    lambda inner: (st.lists(inner, max_size=6)
                   | st.dictionaries(st.text(max_size=8) | st.integers(0, 9), inner, max_size=6)),
    max_leaves=30,
)


def _valid_payload(type_name: str) -> bytes:
    msg_type = TYPES[type_name]
    return bytes(encode_value(msg_type, msg_type.validate(msg_type.example())))


@st.composite
def _mutated(draw: st.DrawFn, payload: bytes) -> bytes:
    """``payload`` with a few bit flips, a truncation, or bytes spliced in / cut out."""
    data = bytearray(payload)
    for _ in range(draw(st.integers(1, 4))):
        how = draw(st.sampled_from(["flip", "truncate", "insert", "delete", "set"]))
        pos = draw(st.integers(0, max(0, len(data) - 1)))
        if how == "flip" and data:
            data[pos] ^= 1 << draw(st.integers(0, 7))
        elif how == "truncate":
            del data[pos:]
        elif how == "insert":
            data[pos:pos] = draw(st.binary(min_size=1, max_size=8))
        elif how == "delete":
            del data[pos:pos + draw(st.integers(1, 8))]
        elif data:
            # A header byte that claims a big length (array32, map32, str32, bin32) or a nil.
            data[pos] = draw(st.sampled_from([0xDD, 0xDF, 0xDB, 0xC6, 0xC0, 0xFF, 0x9F, 0x8F]))
    return bytes(data)


_AMPLIFIERS = ["empty_lists", "empty_maps", "short_strs", "chunks", "int_boxes", "maps_padded", "nested"]


def _amplifier(kind: str, n: int) -> Any:
    """A document that expands a lot per byte when decoded (or builds many messages), ``n`` items long."""
    if kind == "empty_lists":
        return [[]] * n
    if kind == "empty_maps":
        return [{}] * n
    if kind == "short_strs":
        return ["ab"] * n
    if kind == "chunks":
        return [[[]] * 15] * max(1, n // 16)
    if kind == "int_boxes":
        return {"boxes": [[0, 0, 1, 1]] * n, "labels": [""] * n, "scores": [0] * n}
    if kind == "maps_padded":
        return [{"pad": "a" * (32 * n)}, *([{}] * n)]
    return {"a": [[[[]] * 3] * 3] * max(1, n // 13), "b": [{"c": [{}]}] * max(1, n // 4)}


@st.composite
def _amplification_payloads(draw: st.DrawFn) -> tuple[str, bytes]:
    type_name = draw(st.sampled_from(TYPE_NAMES))
    kind = draw(st.sampled_from(_AMPLIFIERS))
    # Hypothesis favours small numbers: ask for the large sizes, where the multiple matters, explicitly.
    n = draw(st.integers(1, 20_000) | st.sampled_from([4096, 16_384, 20_000]))
    document = _amplifier(kind, n)
    if draw(st.booleans()):
        # Inside the type's own document, under one of its field names, where the codec will look.
        unpacker = msgpack.Unpacker(raw=False, strict_map_key=False)
        unpacker.feed(_valid_payload(type_name))
        valid = unpacker.unpack()  # the document alone (array bins may follow it)
        if isinstance(valid, dict) and valid:
            valid[draw(st.sampled_from(sorted(valid)))] = document
            document = valid
    return type_name, msgpack.packb(document, use_bin_type=True)


# -- properties ---------------------------------------------------------------------------------


@settings(_PROFILE, max_examples=300)
@given(type_name=st.sampled_from(TYPE_NAMES), payload=st.binary(max_size=256))
def test_random_bytes_decode_or_raise_codec_error(type_name: str, payload: bytes) -> None:
    _decode_within_bounds(type_name, payload)


@settings(_PROFILE, max_examples=300)
@given(type_name=st.sampled_from(TYPE_NAMES), document=_documents)
def test_random_msgpack_documents_decode_or_raise_codec_error(type_name: str, document: Any) -> None:
    _decode_within_bounds(type_name, msgpack.packb(document, use_bin_type=True))


@settings(_PROFILE, max_examples=400)
@given(data=st.data(), type_name=st.sampled_from(TYPE_NAMES))
def test_mutated_valid_payloads_decode_or_raise_codec_error(data: st.DataObject, type_name: str) -> None:
    _decode_within_bounds(type_name, data.draw(_mutated(_valid_payload(type_name))))


@settings(_PROFILE, max_examples=60)
@given(case=_amplification_payloads())
def test_amplification_payloads_stay_within_a_fixed_multiple_of_their_size(case: tuple[str, bytes]) -> None:
    type_name, payload = case
    _decode_within_bounds(type_name, payload)


@pytest.mark.parametrize("type_name", TYPE_NAMES)
def test_valid_payloads_still_decode_under_the_limits(type_name: str) -> None:
    msg_type = TYPES[type_name]
    value = msg_type.validate(msg_type.example())
    payload = bytes(encode_value(msg_type, value))
    assert values_equal(decode_value(msg_type, payload), value)
    assert _decode_within_bounds(type_name, payload)[0] == "ok"


# -- hostile payloads of a few MB ---------------------------------------------------------------

_FIVE_MB = 5_000_000


def _hostile(kind: str) -> bytes:
    n = _FIVE_MB - 5
    if kind == "empty_lists":  # 1 byte -> a 56-byte list: ~72x when decoded without limits
        return b"\xdd" + n.to_bytes(4, "big") + b"\x90" * n
    if kind == "empty_maps":
        return b"\xdd" + n.to_bytes(4, "big") + b"\x80" * n
    if kind == "nils_in_lists":
        n //= 16
        return b"\xdd" + n.to_bytes(4, "big") + (b"\x9f" + b"\xc0" * 15) * n
    # [[[] x 15] x N]: every list within any type's max_array_len; stopped by max_arrays / the budget.
    n //= 16
    return b"\xdd" + n.to_bytes(4, "big") + (b"\x9f" + b"\x90" * 15) * n


@pytest.mark.parametrize("kind", ["empty_lists", "empty_maps", "nils_in_lists", "chunks"])
@pytest.mark.parametrize("type_name", ["String", "Detections", "DetectionsMultiSource", "Image", "JointTrajectory"])
def test_a_hostile_payload_is_rejected_fast_and_cheaply(type_name: str, kind: str) -> None:
    payload = _hostile(kind)
    start = time.perf_counter()
    outcome, peak = _decode_within_bounds(type_name, payload)
    elapsed = time.perf_counter() - start
    assert outcome == "CodecError"
    # Unbounded, these took 1-3 s and 60-76x the payload in memory (and DetectionsMultiSource of
    # empty maps ~150 s and 1000x); bounded, the worst measured 0.3 s under tracemalloc.
    assert elapsed < 2.0, f"{type_name} took {elapsed:.2f} s to reject {kind}"
    assert peak < 8 * len(payload), f"{type_name}: {kind} peaked at {peak} bytes"


def test_an_oversized_document_is_refused_before_it_is_unpacked() -> None:
    big = msgpack.packb("x" * (17 * 1024 * 1024))
    with pytest.raises(CodecError, match=r"larger than 16777216 bytes \(DecodeLimits.max_document_bytes"):
        decode_value(get_type("String"), big)
    with pytest.raises(CodecError, match="max_arrays"):
        decode_value(get_type("Image"), msgpack.packb({"x": [[]] * 30} | {f"k{i}": [[]] * 30 for i in range(10)}))
    with pytest.raises(CodecError, match="expands to more than 32x its size"):
        decode_value(get_type("DetectionsMultiSource"), msgpack.packb([{}] * 5000))
    with pytest.raises(CodecError, match="more than 4096 maps"):  # padded: within the memory budget
        decode_value(get_type("DetectionsMultiSource"), msgpack.packb([{"pad": "a" * 200_000}, *[{}] * 5000]))
    with pytest.raises(CodecError, match=r"exceeds a decode limit .*max_array_len"):
        decode_value(get_type("Image"), msgpack.packb({"data": {"__ndarray__": b"", "dtype": "|u1",
                                                                "shape": [0] * 33}}))
    with pytest.raises(CodecError, match="ext type"):
        unpack(msgpack.packb(msgpack.ExtType(5, b"")))
    with pytest.raises(CodecError, match="max_ext_len"):
        unpack(b"\xd6\xff\x00\x00\x00\x00")  # the msgpack timestamp ext


def test_limits_are_per_type_configurable_and_validated() -> None:
    detections = get_type("Detections")
    many = msgpack.packb({"boxes": [[0.0, 0.0, 1.0, 1.0]] * 70_000, "labels": ["a"] * 70_000,
                          "scores": [0.5] * 70_000})
    with pytest.raises(CodecError, match="max_array_len"):
        decode_value(detections, many)
    before = decode_limits("Detections")
    try:
        raised = set_decode_limits(detections, max_array_len=100_000, max_arrays=100_000)
        assert decode_limits(detections) == raised and raised.max_map_len == before.max_map_len
        assert decode_value(detections, many).boxes.shape == (70_000, 4)
    finally:
        set_decode_limits("Detections", before)
    assert decode_limits("Detections") == before
    with pytest.raises(CodecError, match="max_array_len"):
        decode_value(detections, many)
    with pytest.raises(CodecError, match="max_maps must be an int >= 0"):
        DecodeLimits(max_maps=-1)
    with pytest.raises(CodecError, match="max_expansion must be an int >= 1"):
        DecodeLimits(max_expansion=0)
    with pytest.raises(CodecError, match="set_decode_limits"):
        set_decode_limits("Detections", max_boxes=3)  # type: ignore[arg-type]


def test_user_codecs_get_default_limits_or_their_own() -> None:
    register_codec("_Bounded", lambda v: v, lambda d: d)
    assert decode_limits("_Bounded") == DEFAULT_DECODE_LIMITS
    register_codec("_Bounded", lambda v: v, lambda d: d, limits=DecodeLimits(max_array_len=4))
    assert decode_limits("_Bounded").max_array_len == 4
    with pytest.raises(CodecError, match="limits must be a DecodeLimits"):
        register_codec("_Bounded", lambda v: v, lambda d: d, limits={"max_array_len": 4})  # type: ignore[arg-type]


# -- arrays whose shape lies ----------------------------------------------------------------------


def _image_doc(shape: list[int], data: bytes, **extra: Any) -> bytes:
    return msgpack.packb({"data": {"__ndarray__": data, "dtype": "|u1", "shape": shape}, "encoding": "rgb8",
                          **extra})


@pytest.mark.parametrize(("shape", "data", "reason"), [
    ([480, 640, 3], bytes(10), "needs 921600 bytes, its bin has 10"),
    ([0, 2**40, 3], b"", "absurd dimensions"),
    ([2**32 - 1, 2**32 - 1, 2**32 - 1], bytes(3), "needs"),  # the product is exact, never wraps to 3
    ([0, 2**32 - 1, 2**32 - 1, 2**32 - 1], b"", "absurd dimensions"),
    ([0, 2**21, 3], b"", "exceeds MAX_IMAGE_SIDE"),
], ids=["short_data", "0x2^40", "product_2^96", "nonzero_product_overflows", "side_2^21"])
def test_an_image_whose_shape_lies_is_refused_naming_the_field(shape: list[int], data: bytes, reason: str) -> None:
    with pytest.raises(CodecError, match="field 'data'") as info:
        decode_value(get_type("Image"), _image_doc(shape, data))
    assert reason in str(info.value)


def test_a_lying_array_is_named_where_it_sits_and_trailing_bins_are_checked_too() -> None:
    inner = {"data": {"__ndarray__": 0, "dtype": "|u1", "shape": [4, 4, 3]}, "encoding": "rgb8"}
    doc = msgpack.packb([{"boxes": [], "labels": [], "scores": [], "image": inner}])
    payload = doc + b"\xc4\x05" + bytes(5)  # a trailing bin of 5 bytes for a 48-byte array
    with pytest.raises(CodecError, match=r"field '\[0\].image.data': array of shape \[4, 4, 3\].*its bin has 5"):
        decode_value(get_type("DetectionsMultiSource"), payload)
    for type_name, doc_ in [("Audio", {"data": {"__ndarray__": b"\0\0", "dtype": "<i2", "shape": [2]}}),
                            ("OccupancyGrid", {"data": {"__ndarray__": b"", "dtype": "|i1", "shape": [2**33, 0]}}),
                            ("LaserScan", {"ranges": {"__ndarray__": b"", "dtype": "<f4", "shape": [8]}}),
                            ("Float32MultiArray", {"__ndarray__": b"", "dtype": "<f4", "shape": [0, 2**40]})]:
        with pytest.raises(CodecError, match=r"needs|absurd"):
            decode_value(get_type(type_name), msgpack.packb(doc_))


def test_valid_images_keep_the_zero_copy_path() -> None:
    pixels = np.arange(480 * 640 * 3, dtype=np.uint8).reshape(480, 640, 3)
    payload = encode_value(get_type("Image"), ImageMsg(data=pixels))
    image = decode_value(get_type("Image"), payload)
    assert np.array_equal(image.data, pixels)
    assert image.data.base is not None and not image.data.flags.writeable  # a view of the payload
    boxes = DetectionsMsg(boxes=np.ones((3, 4)), labels=["a", "b", "c"], scores=np.ones(3), image=image)
    assert values_equal(decode_value(get_type("Detections"), encode_value(get_type("Detections"), boxes)), boxes)


# -- over a real Zenoh session --------------------------------------------------------------------


@pytest.fixture
def listening() -> Iterator[tuple[ZenohTransport, Any]]:
    """A framework transport listening on loopback and a raw Zenoh session (the hostile peer) connected to it."""
    port = free_tcp_port()
    transport = ZenohTransport(listen=[f"tcp/127.0.0.1:{port}"], connect=[], zenoh_options={"scouting/delay": 50})
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", "[]")
    conf.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    raw = zenoh.open(conf)
    try:
        yield transport, raw
    finally:
        raw.close()
        transport.close()


def test_a_hostile_sample_is_counted_quickly_while_another_topic_keeps_flowing(
    listening: tuple[ZenohTransport, Any],
) -> None:
    transport, raw = listening
    suffix = time.monotonic_ns() % 10**9
    hostile_topic = Topic(f"bounds_text_{suffix}", "String")
    steady_topic = Topic(f"bounds_steady_{suffix}", "Int64", qos_profile=QoSConfig(depth=1000))
    texts: list[str] = []
    arrivals: list[float] = []
    hostile_sub = transport.create_subscription(hostile_topic, texts.append)
    transport.create_subscription(steady_topic, lambda _: arrivals.append(time.monotonic()))
    # One peer sends both: its samples arrive over one link, decoded one after another, so a
    # slow decode of the hostile topic would hold back the steady one.
    # Congestion control BLOCK: Zenoh's default (DROP) may drop a 5 MB sample under load, and the
    # count below must see every hostile sample arrive.
    hostile_pub = raw.declare_publisher(transport.key_expr(hostile_topic),
                                        encoding=zenoh.Encoding("application/msgpack").with_schema("String"),
                                        congestion_control=zenoh.CongestionControl.BLOCK)
    steady_pub = raw.declare_publisher(transport.key_expr(steady_topic),
                                       encoding=zenoh.Encoding("application/msgpack").with_schema("Int64"))
    assert wait_for(lambda: hostile_pub.matching_status.matching and steady_pub.matching_status.matching)
    stop = threading.Event()

    def steady() -> None:
        i = 0
        while not stop.is_set():
            steady_pub.put(msgpack.packb(i))
            i += 1
            time.sleep(0.005)

    sender = threading.Thread(target=steady, daemon=True)
    sender.start()
    try:
        assert wait_for(lambda: len(arrivals) >= 10), "the steady topic never started flowing"
        start = time.monotonic()
        hostile = _hostile("empty_lists")
        for _ in range(3):
            hostile_pub.put(hostile)
        assert wait_for(lambda: hostile_sub.statistics().decode_errors == 3, timeout=10), hostile_sub.statistics()
        rejected_after = time.monotonic() - start
        flowing = len(arrivals)
        assert wait_for(lambda: len(arrivals) >= flowing + 10), "the steady topic stopped"
    finally:
        stop.set()
        sender.join(timeout=5)
    during = [t for t in arrivals if t >= start - 0.05]
    gaps = [b - a for a, b in itertools.pairwise(during)]
    assert texts == []
    # Unbounded, each 5 MB sample held the link's thread ~2 s (a 6 s gap on the steady topic).
    assert rejected_after < 3.0, f"three hostile samples took {rejected_after:.2f} s to reject"
    assert max(gaps) < 1.0, f"the steady topic stalled for {max(gaps):.2f} s"
    hostile_pub.undeclare()
    steady_pub.undeclare()
