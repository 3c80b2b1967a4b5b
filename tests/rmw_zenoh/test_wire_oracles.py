"""rmw_zenoh's wire format checked against oracles no one here wrote.

- CDR: every standard type's payload equals ``rclpy.serialization.serialize_message`` of the same message (but for
  alignment padding, which Fast CDR leaves uninitialised and we write as zeros), and rclpy reads it back;
- type hashes: equal to the ``type_hashes`` of the installed ROS packages' ``share/<pkg>/<kind>/<Type>.json``;
- keys and name mangling: equal to ``pamoja-ros2`` (an independent implementation on PyPI);
- attachments: decoded by Zenoh's own deserializer (``zenoh.ext.z_deserialize``).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import attrs
import pytest

pytest.importorskip("rclpy", reason="needs the ros2 extra (the oracle)")
pytest.importorskip("rosbags", reason="needs the rmw_zenoh extra")
pytest.importorskip("agents_interfaces", reason="needs agents_interfaces")

from rclpy.serialization import deserialize_message, serialize_message

from agents_core import messages as m
from agents_core.supported_types import get_type, registered_types
from agents_ros2.conversions import to_ros
from agents_zenoh.rmw import typesupport
from agents_zenoh.rmw.codec import codec_for
from agents_zenoh.rmw.typesupport import ros_types
from agents_zenoh.rmw.wire import (
    DEFAULT_QOS,
    Qos,
    TokenError,
    data_key,
    decode_attachment,
    encode_attachment,
    entity_token,
    gid_of,
    mangle,
    parse_token,
    qos_from_string,
    qos_to_string,
)

pytestmark = pytest.mark.ros2

UNSTAMPED = {"Point", "Pose", "Twist", "Odometry", "OccupancyGrid"}


def _share() -> list[Path]:
    roots = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p] + [sys.prefix]
    return [Path(r) / "share" for r in roots]


def _installed_hash(ros_type: str) -> str:
    pkg, kind, name = ros_type.split("/")
    for share in _share():
        path = share / pkg / kind / f"{name}.json"
        if path.is_file():
            entry = json.loads(path.read_text())["type_hashes"][0]
            assert entry["type_name"] == ros_type
            return str(entry["hash_string"])
    raise AssertionError(f"no installed type description for {ros_type}")


@pytest.mark.parametrize("type_name", sorted(registered_types()))
def test_cdr_equals_rclpy_and_reads_back(type_name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    msg_type = get_type(type_name)
    value = msg_type.validate(msg_type.example())
    codec = codec_for(msg_type)
    payload = codec.encode(value)
    message = to_ros(msg_type, value)
    reference = serialize_message(message)
    # Byte for byte, except padding: Fast CDR leaves alignment gaps as whatever its buffer held (ours are zero)
    # and rclpy's buffer may end in a few bytes past the message (its size estimate; rmw_zenoh sends the exact
    # length, as we do).
    assert len(reference) - 16 <= len(payload) <= len(reference)
    differ = [i for i, (a, b) in enumerate(zip(payload, reference, strict=False)) if a != b]
    assert all(payload[i] == 0 for i in differ), differ
    assert len(differ) <= 3 * len(payload) // 8
    ours, theirs = deserialize_message(payload, type(message)), deserialize_message(reference, type(message))
    assert repr(ours) == repr(theirs)  # repr: NaN covariances compare unequal
    # What a publisher sends: the same bytes written into its reused buffer, whatever that held before
    # (reused from any size on here; a publisher reuses it from REUSE_MIN_BYTES on).
    monkeypatch.setattr(typesupport, "REUSE_MIN_BYTES", 0)
    assert codec.encode_into(value, None) == payload
    assert codec.encode_into(value, bytearray(b"\xa5" * len(payload))) == payload
    assert codec.encode_into(value, bytearray(3)) == payload
    back = codec.decode(payload)
    if type_name in UNSTAMPED:
        strip = {"header": m.Header(stamp_ns=0)}
        assert m.values_equal(attrs.evolve(back, **strip) if hasattr(back, "header") else back,
                              attrs.evolve(value, **strip) if hasattr(value, "header") else value)
    else:
        assert m.values_equal(back, value)


@pytest.mark.parametrize("type_name", sorted(registered_types()))
def test_type_hash_equals_the_installed_description(type_name: str) -> None:
    codec = codec_for(get_type(type_name))
    assert codec.type_hash == _installed_hash(codec.ros_type)


@pytest.mark.parametrize("service", ["lifecycle_msgs/srv/GetState", "lifecycle_msgs/srv/ChangeState",
                                     "agents_interfaces/srv/JsonCall", "std_srvs/srv/Trigger"])
def test_service_type_hash_equals_the_installed_description(service: str) -> None:
    assert ros_types().type_hash(service) == _installed_hash(service)


def test_data_key_equals_pamoja() -> None:
    pamoja = pytest.importorskip("pamoja.ros2", reason="pamoja-ros2 is the independent oracle")
    codec = codec_for(get_type("String"))
    for name in ("/chatter", "/robot1/camera/image_raw"):
        ours = data_key(21, name, codec.ros_type, codec.type_hash)
        assert ours == pamoja.entity_key(21, name, codec.ros_type, codec.type_hash)
        assert ours.startswith(f"21/{name.strip('/')}/std_msgs::msg::dds_::String_/RIHS01_")
        assert pamoja.dds_type_name(codec.ros_type) == codec.dds_type
        assert mangle(name) == pamoja.percent_mangle(name)
        digest = pamoja.type_hash_digest(codec.type_hash)
        assert digest is not None and bytes(digest).hex() == codec.type_hash.removeprefix("RIHS01_")


def test_tokens_as_rmw_zenoh_writes_them() -> None:
    h = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
    node = entity_token(0, "aac3178e146ba6f1fc6e6a4085e77f21", 0, 0, "NN", "/", "talker")
    assert node == "@ros2_lv/0/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/talker"
    pub = entity_token(0, "aac3178e146ba6f1fc6e6a4085e77f21", 0, 10, "MP", "/", "talker", name="/chatter",
                       ros_type="std_msgs::msg::dds_::String_", type_hash=h, qos=Qos(depth=7))
    assert pub == ("@ros2_lv/0/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MP/%/%/talker/%chatter/"
                   f"std_msgs::msg::dds_::String_/{h}/::,7:,:,:,,")
    parsed = parse_token(pub)
    assert (parsed.kind, parsed.node, parsed.name, parsed.qos) == ("MP", "talker", "/chatter", Qos(depth=7))
    assert parse_token(entity_token(3, "z", 1, 2, "SS", "/ns/a", "n", name="/ns/a/srv", ros_type="p::srv::dds_::T_",
                                    type_hash=h)).namespace == "/ns/a"


@pytest.mark.parametrize("qos", [DEFAULT_QOS, Qos(reliability=2, durability=1, history=2, depth=1),
                                 Qos(deadline=(1, 5), lifespan=(2, 0), liveliness=3, lease=(0, 7))])
def test_qos_string_round_trips(qos: Qos) -> None:
    assert qos_from_string(qos_to_string(qos)) == qos
    assert qos_to_string(DEFAULT_QOS) == "::,:,:,:,,"


@pytest.mark.parametrize("bad", ["", "@ros2_lv/0/z/0/0/XX/%/%/n", "@ros2_lv/x/z/0/0/NN/%/%/n",
                                 "@ros2_lv/0/z/0/0/MP/%/%/n/%t/T/H", "@ros2_lv/0/z/0/0/MP/%/%/n/%t/T/H/1:2",
                                 "@ros2_lv/0/z/0/0/MP/%/%/n/%t/T/H/9::,:,:,:,,", "other/0/z/0/0/NN/%/%/n",
                                 "@ros2_lv/0/z/0//NN/%/%/n", "@ros2_lv/0/z/0/0/NN/%/%/n/extra"])
def test_bogus_tokens_are_refused(bad: str) -> None:
    with pytest.raises(TokenError):
        parse_token(bad)


def test_gid_is_xxh3_128_of_the_token_low_half_first() -> None:
    xxhash = pytest.importorskip("xxhash")
    token = "@ros2_lv/0/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MP/%/%/talker/%chatter/T/H/::,7:,:,:,,"
    digest = xxhash.xxh3_128(token.encode()).digest()  # canonical form: big-endian, high half first
    assert gid_of(token) == digest[8:][::-1] + digest[:8][::-1]
    assert gid_of(token) != gid_of(token + "x")


def test_attachment_is_zenohs_serialization() -> None:
    zext = pytest.importorskip("zenoh.ext")
    zenoh = pytest.importorskip("zenoh")
    gid = bytes(range(16))
    data = encode_attachment(1, 1_700_000_000_123_456_789, gid)
    seq, stamp, raw_gid = zext.z_deserialize(tuple[zext.Int64, zext.Int64, bytes], zenoh.ZBytes(data))
    assert (seq, stamp, raw_gid) == (1, 1_700_000_000_123_456_789, gid)
    expected = zext.z_serialize((zext.Int64(7), zext.Int64(-3), gid)).to_bytes()
    assert encode_attachment(7, -3, gid) == expected
    assert decode_attachment(expected) == (7, -3, gid)
