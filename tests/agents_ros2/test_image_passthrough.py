"""A received image published again unchanged sends its ROS sequence without a copy; anything else is copied."""

from __future__ import annotations

import array

import numpy as np
import pytest

pytest.importorskip("rclpy", reason="needs the ros2 extra")
pytest.importorskip("agents_interfaces", reason="needs agents_interfaces (pip install --no-build-isolation "
                                                "./interfaces)")

from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Image as RosImage

from agents_core import messages as m
from agents_ros2.conversions.base import seq
from agents_ros2.conversions.media import image_from_ros, image_to_ros

pytestmark = pytest.mark.ros2


def _received(height: int = 48, width: int = 64) -> RosImage:
    """An rgb8 image as a subscriber gets it: deserialized from CDR, its data an array.array."""
    pixels = np.random.default_rng(7).integers(0, 256, (height, width, 3), dtype=np.uint8)
    sent = image_to_ros(m.ImageMsg(data=pixels, encoding="rgb8"))
    msg = deserialize_message(serialize_message(sent), RosImage)
    assert isinstance(msg.data, array.array)
    return msg


def test_a_received_image_published_again_shares_its_sequence() -> None:
    msg = _received()
    value = image_from_ros(msg)
    out = image_to_ros(value)
    assert out.data is msg.data
    again = deserialize_message(serialize_message(out), RosImage)
    np.testing.assert_array_equal(image_from_ros(again).data, value.data)


def test_a_changed_or_partial_image_is_copied() -> None:
    msg = _received()
    value = image_from_ros(msg)
    changed = value.data.copy()
    changed[0, 0, 0] ^= 0xFF
    out = image_to_ros(m.ImageMsg(data=changed, encoding="rgb8"))
    assert out.data is not msg.data
    assert bytes(out.data) == changed.tobytes()
    # A crop views part of the received buffer: its own (contiguous) pixels are sent, copied.
    crop = value.data[8:24]
    out = image_to_ros(m.ImageMsg(data=crop, encoding="rgb8"))
    assert out.data is not msg.data
    assert bytes(out.data) == np.ascontiguousarray(crop).tobytes()
    # A view that starts later in the buffer but has the same length cannot exist; one that starts
    # at the same place but is shorter is copied too.
    head = np.frombuffer(msg.data, np.uint8)[: len(msg.data) - 3]
    assert seq("B", head, np.uint8) is not msg.data


def test_a_sequence_of_another_item_type_is_copied() -> None:
    floats = array.array("f", [1.0, 2.0, 3.0])
    as_bytes = np.frombuffer(floats, np.uint8)
    out = seq("B", as_bytes, np.uint8)
    assert out is not floats
    assert out.typecode == "B"
    assert bytes(out) == floats.tobytes()
    same = seq("f", np.frombuffer(floats, np.float32), np.float32)
    assert same is floats
