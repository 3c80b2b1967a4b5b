"""The standard types added in issue 15 on ROS 2: exact conversions through CDR bytes, foreign layouts,
bad messages refused with the reason, and a bad message on a live subscription counted, not fatal."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

pytest.importorskip("rclpy", reason="needs the ros2 extra")
pytest.importorskip("agents_interfaces", reason="needs agents_interfaces (pip install --no-build-isolation "
                                                "./interfaces)")

import rclpy
from agents_interfaces.msg import RGBD as RosRGBD
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Image as RosImage
from sensor_msgs.msg import Imu as RosImu
from sensor_msgs.msg import PointCloud2 as RosPointCloud2
from sensor_msgs.msg import PointField

from agents_core import messages as m
from agents_core.errors import TypeValidationError
from agents_core.supported_types import SupportedType, get_type
from agents_core.testing.helpers import wait_for
from agents_core.testing.pairs import ros2_pair
from agents_core.topics import Topic
from agents_ros2.conversions import conversion_for, from_ros, to_ros

pytestmark = pytest.mark.ros2

NEW_TYPES = ("RGBD", "PointCloud2", "Imu", "NavSatFix", "Path", "PoseArray", "MapMetaData", "CameraInfo")
ROS_TYPES = {"RGBD": "agents_interfaces/RGBD", "PointCloud2": "sensor_msgs/PointCloud2", "Imu": "sensor_msgs/Imu",
             "NavSatFix": "sensor_msgs/NavSatFix", "Path": "nav_msgs/Path", "PoseArray": "geometry_msgs/PoseArray",
             "MapMetaData": "nav_msgs/MapMetaData", "CameraInfo": "sensor_msgs/CameraInfo"}


def _wire(msg_type: type[SupportedType], value: object) -> Any:
    data = serialize_message(to_ros(msg_type, value))
    return from_ros(msg_type, deserialize_message(data, conversion_for(msg_type).ros_type))


@pytest.mark.parametrize("name", NEW_TYPES)
def test_new_types_are_exact_through_cdr(name: str) -> None:
    msg_type = get_type(name)
    value = msg_type.example()
    ros_type = conversion_for(msg_type).ros_type
    assert f"{ros_type.__module__.split('.')[0]}/{ros_type.__name__}" == ROS_TYPES[name]
    assert m.values_equal(_wire(msg_type, value), value)


def test_header_stamp_and_frame_are_kept() -> None:
    for name in ("RGBD", "PointCloud2", "Imu", "NavSatFix", "Path", "PoseArray", "CameraInfo"):
        value = get_type(name).example()
        ros = to_ros(get_type(name), value)
        assert (ros.header.stamp.sec, ros.header.stamp.nanosec) == divmod(value.header.stamp_ns, 10**9), name
        assert ros.header.frame_id == value.header.frame_id != "", name


def test_imu_nan_covariance_survives() -> None:
    back = _wire(get_type("Imu"), get_type("Imu").example())
    assert np.isnan(back.linear_acceleration_covariance).all() and back.orientation_covariance[0] == -1


def _cloud(fields: list[tuple[str, int, int]], step: int, width: int, height: int = 1, row_step: int | None = None,
           data: bytes | None = None, big_endian: bool = False) -> RosPointCloud2:
    row_step = step * width if row_step is None else row_step
    return RosPointCloud2(height=height, width=width, point_step=step, row_step=row_step, is_bigendian=big_endian,
                          fields=[PointField(name=n, offset=o, datatype=d, count=1) for n, o, d in fields],
                          data=bytes(row_step * height) if data is None else data)


XYZ = [("x", 0, PointField.FLOAT32), ("y", 4, PointField.FLOAT32), ("z", 8, PointField.FLOAT32)]


def test_point_cloud_offsets_strides_and_padding_are_read() -> None:
    # 2x2 organised cloud, x y z + intensity at 16, 20-byte points, rows padded to 48 bytes.
    fields = [*XYZ, ("intensity", 16, PointField.FLOAT32)]
    rows = []
    for r in range(2):
        points = np.zeros(2, np.dtype({"names": ["x", "y", "z", "intensity"], "formats": ["<f4"] * 4,
                                       "offsets": [0, 4, 8, 16], "itemsize": 20}))
        points["x"], points["intensity"] = [r, r + 0.5], [10 * r, 10 * r + 1]
        rows.append(points.tobytes() + bytes(8))
    cloud = from_ros(get_type("PointCloud2"), _cloud(fields, 20, 2, height=2, row_step=48, data=b"".join(rows)))
    assert cloud.points.shape == (2, 2) and cloud.points.dtype.itemsize == 20
    assert cloud.points["x"].tolist() == [[0, 0.5], [1, 1.5]] and cloud.points["intensity"][1, 1] == 11
    back = to_ros(get_type("PointCloud2"), cloud)
    assert (back.point_step, back.row_step, back.height, back.width) == (20, 40, 2, 2)
    assert [(f.name, f.offset, f.datatype) for f in back.fields] == fields


def test_a_big_endian_cloud_is_read_in_native_order() -> None:
    data = np.array([1.5, 2.5, 3.5], ">f4").tobytes()
    cloud = from_ros(get_type("PointCloud2"), _cloud(XYZ, 12, 1, data=data, big_endian=True))
    assert cloud.points["z"].tolist() == [3.5] and cloud.points.dtype["z"].byteorder in ("<", "=")


@pytest.mark.parametrize(("cloud", "match"), [
    (_cloud(XYZ, 12, 2, data=bytes(20)), r"data has 20 bytes; 1 rows of row_step 24 need 24"),
    (_cloud(XYZ, 12, 2, row_step=16), r"row_step 16 is smaller than width 2 x point_step 12"),
    (_cloud(XYZ, 8, 2), r"field 'z': offset 8 \+ 4 bytes exceeds point_step 8"),
    (_cloud([*XYZ, ("x", 0, PointField.FLOAT32)], 12, 1), r"field 'x' appears twice"),
    (_cloud([*XYZ[:2], ("z", 8, 99)], 12, 1), r"datatype 99"),
    (_cloud(XYZ[:2], 8, 1), r"PointCloud2Msg field 'points': needs a float field 'z'"),
])
def test_bad_point_clouds_are_refused_with_the_reason(cloud: RosPointCloud2, match: str) -> None:
    with pytest.raises(TypeValidationError, match=match):
        from_ros(get_type("PointCloud2"), cloud)


def test_rgbd_with_mismatched_sizes_is_refused() -> None:
    rgbd = RosRGBD()
    rgbd.rgb = to_ros(get_type("Image"), get_type("Image").example())
    rgbd.depth = RosImage(height=2, width=2, encoding="16UC1", step=4, data=bytes(8))
    with pytest.raises(TypeValidationError, match=r"RGBDMsg field 'depth': 2x2 depth does not match the 4x5 image"):
        from_ros(get_type("RGBD"), rgbd)


def test_imu_covariance_of_the_wrong_length_is_refused_on_publish() -> None:
    with pytest.raises(TypeValidationError, match=r"ImuMsg field 'angular_velocity_covariance'"):
        to_ros(get_type("Imu"), m.ImuMsg(angular_velocity_covariance=[np.nan] * 8))


def test_a_bad_message_on_a_live_subscription_is_counted_and_the_next_one_served() -> None:
    with ros2_pair() as (a, b):
        topic = Topic(f"cloud_{id(a) % 10000}", "PointCloud2")
        received: list[Any] = []
        sub = b.create_subscription(topic, received.append)
        pub = a.create_publisher(topic)
        assert wait_for(lambda: (pub.publish(get_type("PointCloud2").example()), bool(received))[1], timeout=10.0,
                        interval=0.1)
        # A raw ROS publisher (a foreign driver) sends a cloud whose data does not match its strides.
        context = rclpy.Context()
        rclpy.init(context=context)
        try:
            node = rclpy.create_node("foreign_lidar", context=context)
            raw = node.create_publisher(RosPointCloud2, "/" + topic.name, 10)
            assert wait_for(lambda: raw.get_subscription_count() > 0, timeout=10.0)
            raw.publish(_cloud(XYZ, 12, 2, data=bytes(20)))
            assert wait_for(lambda: sub.statistics().decode_errors >= 1, timeout=10.0), sub.statistics()
            count = len(received)
            pub.publish(get_type("PointCloud2").example())
            assert wait_for(lambda: len(received) > count, timeout=10.0)  # the subscription keeps serving
            node.destroy_node()
        finally:
            rclpy.shutdown(context=context)
        sub.close()
        pub.close()


def test_the_ros_message_of_an_imu_is_the_standard_one() -> None:
    assert conversion_for(get_type("Imu")).ros_type is RosImu
