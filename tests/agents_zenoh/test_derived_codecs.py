"""Codecs derived from the value classes: the wire format stays byte-identical to the hand-written table.

``golden_payloads.json`` holds the payloads the hand-written codec table (removed in issue 15)
produced for :func:`representative_values`; the derived codecs must reproduce them byte for byte.
The schema text is pinned the same way by ``docs/zenoh-wire-format.md`` (see ``test_codecs.py``).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import attrs
import numpy as np
import pytest

pytest.importorskip("msgpack")

import msgpack

from agents_core import messages as m
from agents_core.messages import values_equal
from agents_core.supported_types import get_type
from agents_core.testing.helpers import free_tcp_port, wait_for
from agents_core.topics import Topic
from agents_zenoh.codecs import CodecError, decode_value, encode_value

pytestmark = pytest.mark.zenoh

GOLDEN = Path(__file__).with_name("golden_payloads.json")
#: The types the hand-written table covered (the golden file's keys).
LEGACY_TYPES = (
    "String", "StreamingString", "Bool", "Int32", "Int64", "Float32", "Float64", "Float32MultiArray",
    "Float64MultiArray", "Image", "CompressedImage", "Audio", "Video", "Detections", "DetectionsMultiSource",
    "Trackings", "TrackingsMultiSource", "PointsOfInterest", "Point", "PointStamped", "Pose", "PoseStamped",
    "Twist", "Odometry", "JointState", "JointTrajectoryPoint", "JointTrajectory", "JointJog", "OccupancyGrid",
    "LaserScan", "ComponentStatus",
)
_FIXED_STAMP = 1_234_567_890_123_456_789


def _pinned(value: Any) -> Any:
    """``value`` with every header stamped "now" (a default Header) given a fixed stamp instead."""
    if isinstance(value, list):
        return [_pinned(v) for v in value]
    if isinstance(value, m.Header):
        return value if value.stamp_ns < 1_720_000_000 * 10**9 else m.Header(_FIXED_STAMP, value.frame_id)
    if attrs.has(type(value)):
        return attrs.evolve(value, **{f.name: _pinned(getattr(value, f.name)) for f in attrs.fields(type(value))
                                      if f.init})
    return value


def representative_values() -> list[tuple[str, Any]]:
    """Every legacy type's example, plus the variants its schema allows (empty, optional parts missing, ...)."""
    values = [(name, _pinned(get_type(name).example())) for name in LEGACY_TYPES]
    h = m.Header(stamp_ns=42, frame_id="cam")
    mono16 = m.ImageMsg(data=np.arange(6, dtype=np.uint16).reshape(2, 3), encoding="mono16", header=h)
    values += [
        ("String", ""),
        ("Int64", -(2**63)),
        ("Float32MultiArray", np.zeros((0, 3), np.float32)),
        ("Float64MultiArray", np.array(2.5)),
        ("Image", mono16),
        ("Audio", m.AudioMsg(data=np.array([0.5, -0.25], np.float32), sample_rate=8000, channels=2, header=h)),
        ("Video", m.VideoMsg(frames=[m.CompressedImageMsg(data=b"jpg", header=h), mono16], header=h)),
        ("Video", m.VideoMsg(header=h)),
        ("Detections", m.DetectionsMsg(header=h)),
        ("Trackings", m.TrackingsMsg(header=h)),
        ("PointsOfInterest", m.PointsOfInterestMsg(points=[[1, 2]], header=h)),
        ("DetectionsMultiSource", []),
        ("JointTrajectory", m.JointTrajectoryMsg(header=h)),
        ("OccupancyGrid", m.OccupancyGridMsg(header=h, origin=m.PoseMsg(header=h))),
        ("LaserScan", m.LaserScanMsg(ranges=[1.5, np.inf], intensities=[0.0, 1.0], header=h)),
    ]
    return values


def _encode_all(encode: Any) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for name, value in representative_values():
        out.setdefault(name, []).append(bytes(encode(get_type(name), value)).hex())
    return out


def test_derived_codecs_write_the_golden_bytes() -> None:
    golden = json.loads(GOLDEN.read_text())
    derived = _encode_all(encode_value)
    assert sorted(golden) == sorted(LEGACY_TYPES)
    for name in LEGACY_TYPES:
        assert derived[name] == golden[name], f"{name}: the derived codec writes other bytes than the legacy one"


def test_derived_codecs_read_the_golden_bytes() -> None:
    golden = json.loads(GOLDEN.read_text())
    by_type: dict[str, list[Any]] = {}
    for name, value in representative_values():
        by_type.setdefault(name, []).append(get_type(name).validate(value))
    for name, payloads in golden.items():
        for payload, value in zip(payloads, by_type[name], strict=True):
            assert values_equal(decode_value(get_type(name), bytes.fromhex(payload)), value), name


# -- the types added with the derivation: structured arrays, third-party decoding, bad samples ----------


def test_a_third_party_reads_a_point_cloud_as_the_document_shows() -> None:
    from tests.agents_zenoh.raw_client import unpack_payload  # noqa: PLC0415  # the doc's own helper

    doc = (Path(__file__).resolve().parents[2] / "docs" / "zenoh-wire-format.md").read_text()
    block = next(b for b in re.findall(r"```python\n(.*?)```", doc, flags=re.S) if "def point_cloud_points" in b)
    namespace: dict[str, Any] = {}
    exec(compile(block, "docs/zenoh-wire-format.md", "exec"), namespace)
    cloud = get_type("PointCloud2").example()
    points = namespace["point_cloud_points"](unpack_payload(bytes(encode_value(get_type("PointCloud2"), cloud))))
    assert values_equal(points, cloud.points)


def _cloud_doc(**changes: Any) -> bytes:
    cloud = get_type("PointCloud2").example()
    raw = cloud.points.view(np.uint8).reshape(-1)
    points = {"fields": [["x", 0, "<f4"], ["y", 4, "<f4"], ["z", 8, "<f4"], ["rgb", 16, "<u4"]], "itemsize": 32,
              "shape": [3], "data": {"__ndarray__": raw.tobytes(), "dtype": "|u1", "shape": [raw.size]}}
    points.update(changes)
    return bytes(msgpack.packb({"points": points, "is_dense": True}))


@pytest.mark.parametrize(("changes", "match"), [
    ({}, None),
    ({"itemsize": 24}, r"field 'points': .*data has 96 bytes; \[3\] records of 24 bytes need 72"),
    ({"shape": [4]}, r"need 128"),
    ({"fields": [["x", 30, "<f4"]]}, r"field 'x' at offset 30 does not fit a 32-byte record"),
    ({"fields": [["x", 0, "|O8"]]}, r"numeric dtype"),
    ({"fields": [["x", 0, "<f4"], ["y", 4, "<f4"]]}, r"PointCloud2Msg field 'points': needs a float field 'z'"),
    ({"shape": [1, 1, 3]}, r"at most 2 sizes"),
])
def test_point_cloud_documents_are_checked(changes: dict[str, Any], match: str | None) -> None:
    if match is None:
        assert decode_value(get_type("PointCloud2"), _cloud_doc()).points["x"].tolist() == [1.0, 2.0, 3.0]
        return
    with pytest.raises(CodecError, match=match):
        decode_value(get_type("PointCloud2"), _cloud_doc(**changes))


def test_an_rgbd_of_mismatched_sizes_is_refused_on_decode() -> None:
    rgbd = get_type("RGBD").example()
    doc = msgpack.unpackb(msgpack.packb({"image": {"data": {"__ndarray__": rgbd.image.data.tobytes(), "dtype": "|u1",
                                                             "shape": [4, 5, 3]}, "encoding": "rgb8"},
                                         "depth": {"data": {"__ndarray__": bytes(8), "dtype": "<u2",
                                                            "shape": [2, 2, 1]}, "encoding": "16UC1"}}))
    with pytest.raises(CodecError, match=r"RGBDMsg field 'depth': 2x2 depth does not match the 4x5 image"):
        decode_value(get_type("RGBD"), msgpack.packb(doc))


def test_a_bad_sample_on_a_live_subscription_is_counted_and_the_next_one_served() -> None:
    zenoh = pytest.importorskip("zenoh")
    from agents_zenoh.transport import ZenohTransport  # noqa: PLC0415  # after the zenoh check

    port = free_tcp_port()
    with ZenohTransport(listen=[f"tcp/127.0.0.1:{port}"], connect=[]) as transport:
        conf = zenoh.Config()
        conf.insert_json5("mode", '"peer"')
        conf.insert_json5("listen/endpoints", "[]")
        conf.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
        conf.insert_json5("scouting/multicast/enabled", "false")
        with zenoh.open(conf) as raw:
            topic = Topic(f"cloud_{port}", "PointCloud2")
            received: list[Any] = []
            sub = transport.create_subscription(topic, received.append)
            pub = raw.declare_publisher(transport.key_expr(topic),
                                        encoding=zenoh.Encoding("application/msgpack").with_schema("PointCloud2"))
            assert wait_for(lambda: pub.matching_status.matching)
            pub.put(_cloud_doc(itemsize=24))
            assert wait_for(lambda: sub.statistics().decode_errors == 1), sub.statistics()
            pub.put(_cloud_doc())
            assert wait_for(lambda: len(received) == 1)  # the subscription keeps serving
            pub.undeclare()
