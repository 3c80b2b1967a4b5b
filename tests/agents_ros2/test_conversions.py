"""Conversions between agents_core values and ROS 2 messages (no DDS involved)."""

from __future__ import annotations

import attrs
import numpy as np
import pytest

pytest.importorskip("rclpy", reason="needs the ros2 extra")
pytest.importorskip("agents_interfaces", reason="needs agents_interfaces (pip install --no-build-isolation "
                                                "./interfaces)")

from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Image as RosImage

from agents_core import messages as m
from agents_core.errors import ConfigError, TypeValidationError
from agents_core.supported_types import SupportedType, get_type, registered_types
from agents_ros2.conversions import conversion_for, from_ros, to_ros

pytestmark = pytest.mark.ros2

#: Types whose ROS message has no header (or a nested pose without one): compared without headers.
UNSTAMPED = {"Point", "Pose", "Twist", "Odometry", "OccupancyGrid"}


def _wire(msg_type: type[SupportedType], value: object) -> object:
    """Value -> ROS message -> CDR bytes -> ROS message -> value, as between two processes."""
    conversion = conversion_for(msg_type)
    data = serialize_message(to_ros(msg_type, value))
    return from_ros(msg_type, deserialize_message(data, conversion.ros_type))


def _without_headers(value: object) -> object:
    if attrs.has(type(value)):
        changes = {f.name: _without_headers(getattr(value, f.name)) for f in attrs.fields(type(value))
                   if f.name != "header"}
        return attrs.evolve(value, **changes, **({"header": m.Header(stamp_ns=0)} if hasattr(value, "header")
                                                 else {}))
    return value


@pytest.mark.parametrize("type_name", sorted(registered_types()))
def test_every_type_survives_serialisation(type_name: str) -> None:
    msg_type = get_type(type_name)
    value = msg_type.validate(msg_type.example())
    back = _wire(msg_type, value)
    if type_name in UNSTAMPED:
        assert m.values_equal(_without_headers(back), _without_headers(value))
    else:
        assert m.values_equal(back, value)


def test_header_stamp_is_exact_at_the_nanosecond() -> None:
    header = m.Header(stamp_ns=1_999_999_999_999_999_999 // 1000 * 1000 + 999, frame_id="base_link")
    image = m.ImageMsg(data=np.zeros((1, 1, 3), np.uint8), header=header)
    ros = to_ros(get_type("Image"), image)
    assert (ros.header.stamp.sec, ros.header.stamp.nanosec) == divmod(header.stamp_ns, 1_000_000_000)
    assert _wire(get_type("Image"), image).header == header


@pytest.mark.parametrize("encoding,dtype,channels", [
    ("rgb8", np.uint8, 3), ("bgr8", np.uint8, 3), ("rgba8", np.uint8, 4), ("bgra8", np.uint8, 4),
    ("mono8", np.uint8, 1), ("mono16", np.uint16, 1), ("16UC1", np.uint16, 1),
])
def test_image_encodings_round_trip(encoding: str, dtype: type[np.generic], channels: int) -> None:
    pixels = np.arange(3 * 5 * channels, dtype=dtype).reshape(3, 5, channels) * 7
    back = _wire(get_type("Image"), m.ImageMsg(data=pixels, encoding=encoding))
    assert back.encoding == encoding
    assert back.data.dtype == dtype and np.array_equal(back.data, pixels)


def _ros_image(encoding: str, width: int, height: int, step: int, data: bytes, big_endian: bool = False) -> RosImage:
    return RosImage(encoding=encoding, width=width, height=height, step=step, data=data,
                    is_bigendian=int(big_endian))


def test_padded_rows_and_foreign_byte_order_are_read() -> None:
    # 2x2 mono16, big-endian, each row padded to 6 bytes.
    rows = [np.array([1, 513], ">u2").tobytes() + b"\0\0", np.array([65535, 2], ">u2").tobytes() + b"\0\0"]
    image = from_ros(get_type("Image"), _ros_image("mono16", 2, 2, 6, b"".join(rows), big_endian=True))
    assert image.data[:, :, 0].tolist() == [[1, 513], [65535, 2]]
    assert image.data.dtype == np.dtype(np.uint16)  # native byte order


@pytest.mark.parametrize("encoding,width,height,step,size,reason", [
    ("yuv422", 2, 2, 4, 8, "encoding 'yuv422' is not supported"),
    ("bayer_rggb8", 2, 2, 2, 4, "is not supported"),
    ("rgb8", 4, 2, 12, 20, "image data has 20 bytes"),
    ("rgb8", 4, 2, 8, 16, "step 8 is smaller"),
])
def test_bad_images_are_rejected_with_the_reason(encoding: str, width: int, height: int, step: int, size: int,
                                                 reason: str) -> None:
    with pytest.raises(TypeValidationError, match=reason):
        from_ros(get_type("Image"), _ros_image(encoding, width, height, step, bytes(size)))


def test_video_keeps_the_order_of_mixed_frames() -> None:
    raw = get_type("Image").example()
    packed = m.CompressedImageMsg(data=b"jpeg bytes", format="jpeg")
    video = m.VideoMsg(frames=[packed, raw, packed, raw])
    back = _wire(get_type("Video"), video)
    assert [type(f).__name__ for f in back.frames] == ["CompressedImageMsg", "ImageMsg"] * 2
    assert m.values_equal(back, video)


def test_multi_array_keeps_its_shape() -> None:
    arr = np.arange(24, dtype=np.float64).reshape(2, 3, 4)
    back = _wire(get_type("Float64MultiArray"), arr)
    assert back.shape == (2, 3, 4) and np.array_equal(back, arr)


def test_tracking_ids_are_64_bit() -> None:
    value = m.TrackingsMsg(ids=[2**62 + 5, -3], labels=["a", "b"], boxes=np.zeros((2, 4)),
                           centroids=np.zeros((2, 2)), estimated_velocities=np.zeros((2, 2)))
    assert _wire(get_type("Trackings"), value).ids.tolist() == [2**62 + 5, -3]


def test_float32_fields_read_back_as_written() -> None:
    grid = m.OccupancyGridMsg(data=np.zeros((2, 3), np.int8), resolution=0.05)
    assert _wire(get_type("OccupancyGrid"), grid).resolution == 0.05


def test_unknown_health_is_rejected() -> None:
    with pytest.raises(TypeValidationError, match="health"):
        to_ros(get_type("ComponentStatus"), m.ComponentStatusMsg(component="x", health="GREAT"))


def test_a_type_without_conversion_names_the_fix() -> None:
    class Unmapped(SupportedType):
        value_class = dict

    with pytest.raises(ConfigError, match="register_conversion"):
        conversion_for(Unmapped)


def test_a_subclass_uses_its_base_conversion() -> None:
    image_type = get_type("Image")

    class CameraImage(image_type):  # type: ignore[misc, valid-type]
        pass

    assert conversion_for(CameraImage) is conversion_for(image_type)
