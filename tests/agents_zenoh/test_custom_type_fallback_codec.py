"""A custom type with neither a value_class nor a ROS message travels on Zenoh as plain msgpack.

Upstream lets a user register such a type with ``add_additional_datatypes`` and publish dicts on
it; the memory transport passes the values by reference, and Zenoh now sends them as plain
msgpack under the default decode limits. Only JSON-like values have a defined wire form: anything
else is refused with an error naming the type, when published and when a peer sends it.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

pytest.importorskip("zenoh")

from agents_core import supported_types
from agents_core.supported_types import SupportedType, add_additional_datatypes
from agents_core.testing.helpers import wait_for
from agents_core.testing.pairs import zenoh_pair
from agents_core.topics import Topic
from agents_zenoh.codecs import DEFAULT_DECODE_LIMITS, CodecError, codec_for, decode_value, encode_value, pack
from agents_zenoh.codecs import registry as codec_registry

pytestmark = pytest.mark.zenoh


class PlainReading(SupportedType):
    """Upstream style: no value_class, no _ros_type: any value validates."""


class PlainReadingChild(PlainReading):
    """A subtype shares its base's codec (same value class)."""


@pytest.fixture(autouse=True, scope="module")
def _registered() -> Iterator[None]:
    """Registered while this module runs, not at import: the conformance suite (collected in the same
    run) parametrizes over the registered types, and these have no example value."""
    add_additional_datatypes([PlainReading, PlainReadingChild])
    yield
    for name in ("PlainReading", "PlainReadingChild"):
        supported_types._registry.unregister(name)
        with contextlib.suppress(Exception):
            codec_registry._codecs.unregister(name)

VALUES: list[Any] = [
    {"sensor": "arm", "ok": True, "reading": [1, 2.5, None, {"nested": ["x", -3]}]},
    [1, "two", 3.0, False],
    "just text",
    42,
    None,
]


def test_json_like_values_cross_a_real_zenoh_pair() -> None:
    with zenoh_pair() as (a, b):
        got: list[Any] = []
        topic = Topic(name="plain_reading", msg_type="PlainReading")
        b.create_subscription(topic, got.append)
        publisher = a.create_publisher(topic)
        assert wait_for(lambda: (publisher.publish({"probe": 0}), bool(got))[1], timeout=10)
        for value in VALUES:
            publisher.publish(value)
        assert wait_for(lambda: got[-1:] == VALUES[-1:], timeout=10), got
    # Late probes (sent while the subscription was matching) may still arrive first.
    assert [v for v in got if v != {"probe": 0}] == VALUES


def test_a_tuple_travels_as_a_list() -> None:
    assert decode_value(PlainReading, encode_value(PlainReading, {"xy": (1, 2)})) == {"xy": [1, 2]}


def test_the_codec_uses_the_default_decode_limits_and_says_what_it_carries() -> None:
    codec = codec_for(PlainReading)
    assert codec.limits == DEFAULT_DECODE_LIMITS
    assert "JSON-like" in codec.schema
    assert codec_for(PlainReadingChild) is codec


@pytest.mark.parametrize(("value", "what"), [
    ({"data": np.zeros(3)}, "ndarray"),
    ({"raw": b"\x00\x01"}, "bytes"),
    ({"tags": {"a", "b"}}, "set"),
    ({1: "int key"}, "str keys only"),
    ({"__ndarray__": 0}, "reserves"),
    ([object()], "object"),
])
def test_other_values_are_refused_on_publish_naming_the_type(value: Any, what: str) -> None:
    with pytest.raises(CodecError, match=rf"PlainReading.*{what}|{what}.*PlainReading"):
        encode_value(PlainReading, value)


def test_a_peer_document_that_is_not_json_like_is_refused() -> None:
    # A peer may send any document: here one with an out-of-band array and one with raw bytes.
    for document in ({"data": np.arange(4)}, {"raw": b"abc"}):
        with pytest.raises(CodecError, match="PlainReading"):
            decode_value(PlainReading, pack(document))


def test_a_document_over_the_default_limits_is_refused() -> None:
    too_long = [0] * (DEFAULT_DECODE_LIMITS.max_array_len + 1)
    with pytest.raises(CodecError, match="PlainReading"):
        decode_value(PlainReading, pack(too_long))


def test_a_refused_value_does_not_reach_the_peer() -> None:
    with zenoh_pair() as (a, b):
        got: list[Any] = []
        topic = Topic(name="plain_refused", msg_type="PlainReading")
        b.create_subscription(topic, got.append)
        publisher = a.create_publisher(topic)
        assert wait_for(lambda: (publisher.publish("probe"), bool(got))[1], timeout=10)
        with pytest.raises(CodecError, match="PlainReading"):
            publisher.publish({"tags": {"a"}})
        publisher.publish("after")
        assert wait_for(lambda: got[-1:] == ["after"], timeout=10)
    assert [v for v in got if v != "probe"] == ["after"]
