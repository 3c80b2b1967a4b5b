"""A Float32 beyond float32's range is refused as such, not as "expects a number, got str".

``agentsctl topics pub x Float32 1e39`` used to say "Float32 expects a number, got str": the parser
tried the number, then the text as a fallback, and reported the fallback's failure.
"""

from __future__ import annotations

import msgpack
import numpy as np
import pytest

from agents_core.cli.values import parse_value
from agents_core.errors import ConfigError, TypeValidationError
from agents_core.ros import Topic
from agents_core.supported_types import get_type
from agents_core.transport.memory import MemoryTransport

FLOAT32 = get_type("Float32")


@pytest.mark.parametrize("text", ["1e39", "-1e39", "3.5e38", "1e300"])
def test_the_cli_names_the_range(text: str) -> None:
    with pytest.raises(ConfigError) as caught:
        parse_value(FLOAT32, text)
    message = str(caught.value)
    assert "overflows float32" in message and "out of range" in message and "got str" not in message


def test_values_within_range_and_non_numbers_keep_their_readings() -> None:
    assert parse_value(FLOAT32, "3.4e38") == 3.4e38
    with pytest.raises(ConfigError, match="expects a number, got str"):
        parse_value(FLOAT32, "abc")
    assert parse_value(get_type("String"), "1e39") == "1e39"  # a String topic still takes the text


def test_validate_names_the_bound() -> None:
    bound = r"overflows float32 \(out of range: \|value\| <= 3\.4028235e\+38"
    for value in (1e39, np.float64(-1e39), 10**39):
        with pytest.raises(TypeValidationError, match=bound):
            FLOAT32.validate(value)


def test_publishing_1e39_on_memory_is_refused_with_the_range() -> None:
    with MemoryTransport() as t:
        publisher = t.create_publisher(Topic(name="numbers", msg_type="Float32"))
        with pytest.raises(TypeValidationError, match="overflows float32"):
            publisher.publish(1e39)


def test_a_zenoh_sample_of_1e39_is_refused_with_the_range() -> None:
    pytest.importorskip("zenoh")
    from agents_zenoh.codecs import CodecError, decode_value  # noqa: PLC0415

    with pytest.raises(CodecError, match="overflows float32"):
        decode_value(FLOAT32, msgpack.packb(1e39))
