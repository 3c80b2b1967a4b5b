"""The msgpack codecs of the Zenoh adapter, without a network."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("msgpack")

import msgpack

from agents_core.messages import Header, ImageMsg, values_equal
from agents_core.supported_types import SupportedType, get_type, registered_types
from agents_core.types import is_builtin_type
from agents_zenoh.codecs import (
    REUSE_ABOVE,
    CodecError,
    builtin_schema_names,
    codec_for,
    decode_value,
    describe_schemas,
    encode_value,
    pack,
    register_codec,
    schema_list,
    unpack,
    update_schema_doc,
)

pytestmark = pytest.mark.zenoh


def _builtin_types() -> dict[str, type[SupportedType]]:
    # Other tests register their own types in the process-wide registry; only the framework's
    # own types are promised a built-in codec.
    return {n: t for n, t in registered_types().items() if is_builtin_type(t)}


@pytest.mark.parametrize("type_name", sorted(_builtin_types()))
def test_every_registered_type_has_a_codec_and_round_trips(type_name: str) -> None:
    msg_type = _builtin_types()[type_name]
    value = msg_type.validate(msg_type.example())
    assert values_equal(decode_value(msg_type, encode_value(msg_type, value)), value)
    assert type_name in describe_schemas()


def test_arrays_travel_after_the_document_aligned_and_without_copies() -> None:
    pixels = np.random.default_rng(1).integers(0, 255, (48, 64, 3), dtype=np.uint8)
    payload = encode_value(get_type("Image"), ImageMsg(data=pixels, header=Header(stamp_ns=7, frame_id="f")))
    unpacker = msgpack.Unpacker(raw=False)
    unpacker.feed(payload)
    document = unpacker.unpack()
    assert document["data"] == {"__ndarray__": 0, "dtype": "|u1", "shape": [48, 64, 3]}
    assert document["header"] == {"stamp_ns": 7, "frame_id": "f"}
    assert [obj for obj in unpacker if obj is not None] == [pixels.tobytes()]
    image = decode_value(get_type("Image"), payload)
    assert image.data.base is not None and not image.data.flags.writeable  # a view of the payload
    floats = unpack(pack({"a": np.arange(5, dtype=np.float64), "b": np.arange(3, dtype=np.float32)}))
    assert floats["a"].flags.aligned and floats["b"].flags.aligned
    assert floats["a"].tolist() == [0, 1, 2, 3, 4]


@pytest.mark.parametrize("array", [
    np.zeros((0, 4), np.float32),
    np.arange(12, dtype=np.int16).reshape(3, 4)[:, ::2],  # not contiguous
    np.arange(6, dtype=">f8"),  # big-endian
    np.array(3.5),  # 0-d
    np.array([True, False]),
    np.arange(4, dtype=np.complex64),
])
def test_array_shapes_and_dtypes(array: np.ndarray[Any, Any]) -> None:
    back = unpack(pack(array))
    assert back.shape == array.shape
    assert np.array_equal(back, array)


def test_a_third_party_may_inline_the_array_bytes() -> None:
    doc = {"data": {"__ndarray__": bytes(range(12)), "dtype": "|u1", "shape": [2, 2, 3]},
           "encoding": "rgb8"}
    image = decode_value(get_type("Image"), msgpack.packb(doc))
    assert image.data.shape == (2, 2, 3) and image.data[1, 1, 2] == 11
    assert image.header.stamp_ns > 0  # a missing header takes the default


@pytest.mark.parametrize(("payload", "reason"), [
    (b"", "empty"),
    (b"\xc1", "invalid msgpack"),
    (b"\x92\x01", "ends inside"),
    (msgpack.packb("text") + b"\x07", "unexpected byte 0x07"),
    (msgpack.packb(42), "String expects str"),
    (msgpack.packb({"data": {"__ndarray__": 0, "dtype": "|u1", "shape": [1, 1, 3]}}), "0 bin"),
    (msgpack.packb({"data": {"__ndarray__": b"ab", "dtype": "|u1", "shape": [1, 1, 3]}}), "needs 3 bytes"),
    (msgpack.packb({"data": {"__ndarray__": b"ab", "dtype": "|O8", "shape": [2]}}), "numeric dtype"),
    (msgpack.packb({"data": {"__ndarray__": b"ab", "dtype": "|u1", "shape": [-2]}}), "non-negative"),
    (msgpack.packb(["not", "a", "map"]), "expected a map"),
    (msgpack.packb({"data": "x", "encoding": "rgb8"}), "field 'data'"),
])
def test_decode_errors_name_the_type_and_the_reason(payload: bytes, reason: str) -> None:
    type_name = "String" if reason in ("empty", "invalid msgpack", "ends inside", "unexpected byte 0x07",
                                       "String expects str") else "Image"
    with pytest.raises(CodecError, match=f"as {type_name}") as info:
        decode_value(get_type(type_name), payload)
    assert reason in str(info.value)


def test_reusable_buffer_for_large_payloads() -> None:
    big = np.ones(2 * REUSE_ABOVE, np.uint8)
    buffer = bytearray()
    assert pack({"x": big}, buffer) is buffer
    assert unpack(bytes(buffer))["x"].size == 2 * REUSE_ABOVE
    assert pack({"x": big[:-100]}, buffer) is buffer  # shrinks to fit
    assert unpack(bytes(buffer))["x"].size == 2 * REUSE_ABOVE - 100
    assert isinstance(pack({"x": big[:10]}, buffer), bytes)  # small payloads do not use it


class _Celsius(SupportedType):
    """A user type with a value class no built-in codec handles.

    Not added to the type registry: that registry is process-wide and other tests iterate it.
    """

    value_class = float


class _NamedImage(SupportedType):
    value_class = ImageMsg


def test_user_types_need_a_codec_unless_they_share_a_value_class() -> None:
    with pytest.raises(CodecError, match=r"register_codec\('_Celsius'"):
        codec_for(_Celsius)
    register_codec("_Celsius", lambda v: {"c": v, "raw": np.array([v])}, lambda d: float(d["raw"][0]),
                   schema='{"c": float, "raw": ndarray <f8}')
    assert decode_value(_Celsius, encode_value(_Celsius, 21.5)) == 21.5
    assert describe_schemas()["_Celsius"] == '{"c": float, "raw": ndarray <f8}'


def test_a_subtype_with_the_same_value_class_uses_its_base_codec() -> None:
    class MyImage(get_type("Image")):  # type: ignore[misc,valid-type]
        """An Image subtype a user might register."""

    image = get_type("Image").example()
    assert values_equal(decode_value(MyImage, encode_value(MyImage, image)), image)
    with pytest.raises(CodecError):
        codec_for(_NamedImage)  # not an Image subclass: no codec to inherit


def test_the_wire_format_document_lists_every_schema() -> None:
    doc = (Path(__file__).resolve().parents[2] / "docs" / "zenoh-wire-format.md").read_text()
    schemas = describe_schemas()
    for name in ["Header", *_builtin_types()]:
        assert f"- **{name}**: `{schemas[name]}`" in doc, f"docs/zenoh-wire-format.md lacks the {name} schema"


def test_the_wire_format_document_schema_list_is_generated_from_the_registry(tmp_path: Path) -> None:
    doc = Path(__file__).resolve().parents[2] / "docs" / "zenoh-wire-format.md"
    assert schema_list(builtin_schema_names()) in doc.read_text(), (
        "docs/zenoh-wire-format.md is out of date: run python -m agents_zenoh.codecs docs/zenoh-wire-format.md")
    copy = tmp_path / "doc.md"
    copy.write_text(doc.read_text().replace("- **Bool**: `bool`\n", "- **Bool**: `old`\n- **Gone**: `x`\n"))
    assert update_schema_doc(str(copy)) and copy.read_text() == doc.read_text()


@pytest.mark.parametrize("document", ["x" * 64, "", 0, -1, 2**63, 1.5, True, None, b"\x00raw"])
def test_plain_scalars_take_one_msgpack_call_both_ways_with_the_same_bytes(document: Any) -> None:
    # The fast paths for what most topics carry must not change the wire or the decoded value.
    payload = pack(document)
    assert payload == msgpack.packb(document, use_bin_type=True)
    assert unpack(payload) == document and type(unpack(payload)) is type(document)
    assert encode_value(get_type("String"), "hi") == msgpack.packb("hi")


def test_a_scalar_head_with_anything_after_it_takes_the_full_path() -> None:
    from agents_zenoh.codecs import DecodeLimits  # noqa: PLC0415

    # Trailing bytes after a string document: refused, named as the full path names them.
    with pytest.raises(CodecError):
        unpack(msgpack.packb("abc") + b"\xc1")
    # A string over the type's limit: the full path's message, naming the limit.
    with pytest.raises(CodecError, match="max_str_len"):
        unpack(msgpack.packb("x" * 50), DecodeLimits(max_str_len=8))
    # Too large for a scalar: the full path's error too.
    with pytest.raises(CodecError, match=r"out of range|Integer"):
        pack(2**70)


def test_a_small_map_without_arrays_decodes_alone_and_one_with_them_or_past_a_limit_takes_the_full_path() -> None:
    from agents_zenoh.codecs import framing  # noqa: PLC0415

    doc = {"kind": "feedback", "feedback": {"step": 3, "action": [0.1, 0.2], "status": "moving"}}
    assert framing.unpack(framing.pack(doc)) == doc
    # A str that merely holds the marker's bytes goes down the full path and decodes the same.
    marked = {"note": "__ndarray__", "n": [1, 2]}
    assert framing.unpack(framing.pack(marked)) == marked
    # Arrays after the document: the full path resolves them.
    with_array = framing.unpack(framing.pack({"a": np.arange(4, dtype=np.int32), "b": {"c": 1}}))
    assert with_array["a"].tolist() == [0, 1, 2, 3] and with_array["b"] == {"c": 1}
    # A limit is still enforced, and named, for a map that the one C call refuses.
    with pytest.raises(framing.CodecError, match="decode limit"):
        framing.unpack(framing.pack({"xs": [1, 2, 3]}), framing.DecodeLimits(max_array_len=2))
