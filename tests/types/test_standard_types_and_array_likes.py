"""The standard types added in issue 15 and the array-likes every array-valued type accepts (no middleware).

Round trips through the Zenoh codec and ROS 2 CDR are in tests/agents_zenoh (every registered type)
and tests/agents_ros2/test_standard_types_cdr.py; the conformance suite runs every type on every transport.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from agents_core import messages as m
from agents_core.callbacks import callback_for
from agents_core.components.wiring import validate_topics
from agents_core.errors import TypeValidationError
from agents_core.supported_types import get_type
from agents_core.testing.helpers import wait_for
from agents_core.topics import Topic
from agents_core.transport.memory import MemoryTransport

NEW_TYPES = ("RGBD", "PointCloud2", "Imu", "NavSatFix", "Path", "PoseArray", "MapMetaData", "CameraInfo")


@pytest.mark.parametrize("name", NEW_TYPES)
def test_new_types_are_registered_with_valid_examples(name: str) -> None:
    msg_type = get_type(name)
    value = msg_type.example()
    assert m.values_equal(msg_type.validate(value), value)
    assert isinstance(value, msg_type.value_class)


def _xyz(n: int = 2) -> np.ndarray[Any, Any]:
    return np.zeros(n, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4")])


# -- bad input is refused naming the type and the field ----------------------------------------------


@pytest.mark.parametrize(("make", "match"), [
    (lambda: m.PointCloud2Msg(points=np.zeros((2, 3), np.float32)), r"PointCloud2Msg field 'points'.*structured"),
    (lambda: m.PointCloud2Msg(points=np.zeros(2, [("x", "<f4"), ("y", "<f4")])), r"points.*float field 'z'"),
    (lambda: m.PointCloud2Msg(points=np.zeros(2, [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("t", "<i8")])),
     r"point field 't' has dtype int64"),
    (lambda: m.PointCloud2Msg(points=np.zeros(2, [("x", ">f4"), ("y", ">f4"), ("z", ">f4")])), "little-endian"),
    (lambda: m.RGBDMsg(image=get_type("Image").example(),
                       depth=m.ImageMsg(data=np.zeros((3, 3), np.uint16), encoding="16UC1")),
     r"RGBDMsg field 'depth': 3x3 depth does not match the 4x5 image"),
    (lambda: m.RGBDMsg(image=get_type("Image").example(), depth=get_type("Image").example()),
     r"RGBDMsg field 'depth': encoding 'rgb8' is not a depth encoding"),
    (lambda: m.ImuMsg(orientation_covariance=[np.nan] * 4), r"ImuMsg field 'orientation_covariance'.*shape 9"),
    (lambda: m.ImuMsg(linear_acceleration=[0, "a", 1]), r"ImuMsg field 'linear_acceleration'"),
    (lambda: m.NavSatFixMsg(status=5), r"NavSatFixMsg field 'status'"),
    (lambda: m.NavSatFixMsg(position_covariance=np.zeros(3)), r"NavSatFixMsg field 'position_covariance'"),
    (lambda: m.PathMsg(poses=[m.PointMsg()]), r"PathMsg field 'poses\[0\]': expected PoseMsg"),
    (lambda: m.PoseArrayMsg(poses="not a list"), r"PoseArrayMsg field 'poses'"),
    (lambda: m.MapMetaDataMsg(width=-1), r"MapMetaDataMsg field 'width'"),
    (lambda: m.CameraInfoMsg(k=[1, 2, 3]), r"CameraInfoMsg field 'k'"),
    (lambda: m.CameraInfoMsg(roi=[0, 0, -1, 4]), r"CameraInfoMsg field 'roi'"),
])
def test_bad_values_are_refused_naming_type_and_field(make: Any, match: str) -> None:
    with pytest.raises(TypeValidationError, match=match):
        make()


@pytest.mark.parametrize(("name", "value", "match"), [
    ("PointCloud2", np.zeros(3, np.float32), "PointCloud2Msg field 'points'"),
    ("RGBD", np.zeros((2, 2, 3), np.uint8), "RGBD expects RGBDMsg or an"),
    ("Imu", {"orientation": [0, 0, 0, 1]}, "Imu expects ImuMsg, got dict"),
    ("CameraInfo", 3, "CameraInfo expects CameraInfoMsg"),
])
def test_a_value_of_the_wrong_kind_is_refused_on_publish(name: str, value: Any, match: str) -> None:
    with MemoryTransport() as t:
        pub = t.create_publisher(Topic("bad", name))
        with pytest.raises(TypeValidationError, match=match):
            pub.publish(value)


# -- RGBD is accepted wherever Image is -----------------------------------------------------------


def test_rgbd_is_accepted_wherever_image_is() -> None:
    image_type, rgbd_type = get_type("Image"), get_type("RGBD")
    assert issubclass(rgbd_type, image_type)
    validate_topics("vlm", "VLM", [Topic("camera", "RGBD")], {"Required": [image_type]}, "input")
    rgbd = rgbd_type.example()
    callback = callback_for(Topic("camera", "RGBD"))
    callback._receive(rgbd)
    assert np.array_equal(callback.get_output(), rgbd.image.data)  # the colour pixels, as for an Image
    assert callback.msg.depth.encoding == "16UC1"  # the depth stays reachable
    assert rgbd.height == 4 and rgbd.width == 5 and rgbd.encoding == "rgb8"


def test_rgbd_wraps_an_image_depth_pair() -> None:
    colour = np.zeros((2, 3, 3), np.uint8)
    depth = np.ones((2, 3), np.float32)
    value = get_type("RGBD").validate((colour, depth))
    assert value.depth.encoding == "32FC1" and value.image.encoding == "rgb8"


def test_point_cloud_layouts() -> None:
    cloud = m.PointCloud2Msg(points=_xyz(4).reshape(1, 4))
    assert cloud.points.shape == (4,)  # one row is an unorganised cloud
    organised = m.PointCloud2Msg(points=_xyz(6).reshape(2, 3))
    assert organised.points.shape == (2, 3) and organised.xyz.shape == (6, 3)
    assert get_type("PointCloud2").validate(_xyz(2)).points.shape == (2,)


# -- array-likes ----------------------------------------------------------------------------------


def test_an_image_from_nested_lists_of_0_to_255_is_uint8() -> None:
    value = get_type("Image").validate([[[0, 128, 255], [1, 2, 3]]])
    assert value.data.dtype == np.uint8 and value.data.shape == (1, 2, 3) and value.encoding == "rgb8"
    mono = m.ImageMsg(data=[[0, 255], [7, 9]], encoding="mono8")
    assert mono.data.dtype == np.uint8 and mono.data.shape == (2, 2, 1)


@pytest.mark.parametrize(("value", "match"), [
    ([[[0, 300, 1]]], r"do not fit uint8"),
    ([[[0, -1, 1]]], r"do not fit uint8"),
    ([[[1, 2, 3]], [[1, 2]]], r"not a rectangular array"),
    ([[["a", "b", "c"]]], r"expected numbers"),
    ("pixels", r"Image expects ImageMsg"),
])
def test_bad_array_likes_are_refused_as_images(value: Any, match: str) -> None:
    with pytest.raises(TypeValidationError, match=match):
        get_type("Image").validate(value)


@pytest.mark.parametrize("name", ["Float32MultiArray", "Float64MultiArray"])
def test_multi_arrays_from_nested_lists(name: str) -> None:
    msg_type = get_type(name)
    value = msg_type.validate([[1, 2, 3], [4.5, 5, 6]])
    assert value.dtype == msg_type.dtype and value.shape == (2, 3)
    with pytest.raises(TypeValidationError, match=f"{name} .*not a rectangular array"):
        msg_type.validate([[1, 2], [3]])
    with pytest.raises(TypeValidationError, match="expected numbers"):
        msg_type.validate([["x"]])


def test_float32_refuses_values_beyond_its_range() -> None:
    with pytest.raises(TypeValidationError, match="beyond float32"):
        get_type("Float32MultiArray").validate([1e40])
    assert np.isinf(get_type("Float32MultiArray").validate([np.inf]))[0]  # inf is a value, not an overflow


@pytest.mark.parametrize(("make", "match"), [
    (lambda: m.OccupancyGridMsg(data=[[0, 300]]), r"OccupancyGridMsg field 'data'.*do not fit int8"),
    (lambda: m.TrackingsMsg(ids=[1.5], labels=["a"], boxes=[[0, 0, 1, 1]], centroids=[[0, 0]],
                            estimated_velocities=[[0, 0]]), r"field 'ids'.*whole numbers"),
    (lambda: m.DetectionsMsg(boxes=[[0, 0, 1]], labels=["a"], scores=[1]), r"field 'boxes': expected shape Nx4"),
    (lambda: m.PoseMsg(position=[[0, 1], [2]]), r"field 'position': not a rectangular array"),
])
def test_array_fields_refuse_bad_array_likes(make: Any, match: str) -> None:
    with pytest.raises(TypeValidationError, match=match):
        make()


def test_array_fields_accept_array_likes() -> None:
    detections = m.DetectionsMsg(boxes=[[0, 0, 10, 10]], labels=["cup"], scores=(0.5,))
    assert detections.boxes.dtype == np.float32 and detections.scores.tolist() == [0.5]
    assert m.OccupancyGridMsg(data=[[0, 100], [-1, 50]]).data.dtype == np.int8


def test_a_model_reply_published_as_it_comes() -> None:
    # The spec's DepthEstimator publishes result["output"]: a JSON reply gives the depth map as nested lists.
    result = {"output": [[0, 10, 20], [30, 40, 255]]}
    with MemoryTransport() as t:
        topic = Topic("depth", "Image")
        received: list[Any] = []
        t.create_subscription(topic, received.append)
        t.create_publisher(topic).publish(result["output"])
        assert wait_for(lambda: bool(received))
        assert received[0].encoding == "mono8" and received[0].data[1, 2, 0] == 255
