"""A received value published again unchanged is sent as the payload it came in; anything else is encoded anew."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("zenoh", reason="needs the zenoh extra")

from agents_core import messages as m
from agents_core.supported_types import Image
from agents_zenoh.codecs import CodecError, decoder_for, encoder_for, pack, unpack


def _payload(frame_id: str = "5") -> bytes:
    pixels = np.random.default_rng(3).integers(0, 256, (48, 64, 3), dtype=np.uint8)
    value = m.ImageMsg(data=pixels, encoding="rgb8", header=m.Header(frame_id=frame_id))
    return bytes(encoder_for(Image)(value, None))


def test_an_unchanged_received_image_is_its_own_payload() -> None:
    payload = _payload()
    value = decoder_for(Image)(payload)
    assert encoder_for(Image)(value, bytearray()) is payload


def test_a_changed_value_is_encoded_anew() -> None:
    encode, decode = encoder_for(Image), decoder_for(Image)
    payload = _payload()
    value = decode(payload)
    # Same pixels (still a view of the payload), another header.
    relabelled = m.ImageMsg(data=value.data, encoding="rgb8", header=m.Header(frame_id="6"))
    out = encode(relabelled, bytearray())
    assert out is not payload
    again = decode(bytes(out))
    assert again.header.frame_id == "6"
    np.testing.assert_array_equal(again.data, value.data)
    # Other pixels: a crop of the received ones, and a changed copy.
    crop = m.ImageMsg(data=value.data[8:24], encoding="rgb8", header=value.header)
    out = encode(crop, bytearray())
    assert out is not payload
    np.testing.assert_array_equal(decode(bytes(out)).data, value.data[8:24])
    changed = value.data.copy()
    changed[0, 0, 0] ^= 0xFF
    out = encode(m.ImageMsg(data=changed, encoding="rgb8", header=value.header), bytearray())
    assert out is not payload
    np.testing.assert_array_equal(decode(bytes(out)).data, changed)


def test_only_a_payload_written_as_pack_writes_it_is_reused() -> None:
    array = np.arange(64, dtype=np.uint8)
    payload = bytes(pack({"a": array}))
    document = unpack(payload)
    assert pack(document) is payload
    # The same array under another key: the document before the bytes differs.
    assert pack({"b": document["a"]}) != payload
    # A payload that views a slice of a larger buffer (a bytes object holding more): not reused.
    larger = payload + bytes(8)
    view = unpack(memoryview(larger)[: len(payload)])
    assert pack(view) is not larger
    assert bytes(pack(view)) == payload
    with pytest.raises(CodecError):  # and trailing bytes that are no bin are refused when decoding
        unpack(payload + b"\x00")
    # Two arrays are always written anew.
    twice = bytes(pack({"a": array, "b": array}))
    decoded = unpack(twice)
    out = pack(decoded)
    assert out is not twice
    assert bytes(out) == twice
