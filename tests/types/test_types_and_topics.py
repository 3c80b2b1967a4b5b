"""Message types, the registry, topics and QoS: validation with clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from agents_core import get_type, registered_types
from agents_core.errors import ConfigError, TopicNameError, TypeValidationError, UnknownTypeError
from agents_core.messages import (
    AudioMsg,
    DetectionsMsg,
    Header,
    ImageMsg,
    OccupancyGridMsg,
    StreamingStringMsg,
    TrackingsMsg,
    values_equal,
)
from agents_core.ros import (
    Audio,
    Bool,
    Detections,
    FixedInput,
    Float32,
    Float32MultiArray,
    Image,
    Int32,
    QoSConfig,
    StreamingString,
    String,
    SupportedType,
    Topic,
    add_additional_datatypes,
)

DESIGN_TYPES = {
    "String", "StreamingString", "Bool", "Int32", "Int64", "Float32", "Float64", "Float32MultiArray",
    "Float64MultiArray", "Image", "CompressedImage", "Audio", "Video", "Detections", "DetectionsMultiSource",
    "Trackings", "TrackingsMultiSource", "PointsOfInterest", "Odometry", "Pose", "PoseStamped", "Point",
    "PointStamped", "Twist", "JointState", "JointTrajectory", "JointTrajectoryPoint", "JointJog",
    "OccupancyGrid", "LaserScan", "ComponentStatus",
}


def test_registry_has_every_design_type() -> None:
    assert set(registered_types()) >= DESIGN_TYPES


@pytest.mark.parametrize("name", sorted(DESIGN_TYPES))
def test_example_values_validate_to_themselves(name: str) -> None:
    t = get_type(name)
    value = t.example()
    assert values_equal(t.validate(value), value)


@pytest.mark.parametrize(
    ("msg_type", "value", "match"),
    [
        (String, b"bytes", "String expects str"),
        (Bool, 1, "Bool expects bool"),
        (Int32, 2**31, "does not fit in 32 bits"),
        (Int32, 1.5, "Int32 expects int"),
        (Float32, "1.0", "expects a number"),
        (Float32, 1e39, "overflows float32"),
        (Float32MultiArray, "text", "expects a numeric array"),
        (Image, np.zeros((4, 4, 3), np.float32), "cannot guess an image encoding"),
        (Image, "not an image", "Image expects ImageMsg"),
        (Audio, np.zeros((2, 2), np.int16), "1-D"),
        (Detections, {"boxes": []}, "Detections expects DetectionsMsg"),
    ],
)
def test_wrong_values_are_rejected_clearly(msg_type: type[SupportedType], value: object, match: str) -> None:
    with pytest.raises(TypeValidationError, match=match):
        msg_type.validate(value)


def test_image_checks_encoding_against_pixels() -> None:
    with pytest.raises(TypeValidationError, match="'rgb8' needs uint8 with 3 channel"):
        ImageMsg(data=np.zeros((2, 2, 4), np.uint8), encoding="rgb8")
    with pytest.raises(TypeValidationError, match="'yuv422' is not supported"):
        ImageMsg(data=np.zeros((2, 2, 3), np.uint8), encoding="yuv422")
    depth = Image.validate(np.zeros((3, 4), np.uint16))
    assert depth.encoding == "16UC1" and depth.data.shape == (3, 4, 1)


def test_image_output_is_rgb() -> None:
    bgr = np.zeros((1, 2, 3), np.uint8)
    bgr[..., 0] = 255  # blue in BGR
    msg = ImageMsg(data=bgr, encoding="bgr8")
    rgb = Image.to_output(msg)
    assert rgb[0, 0].tolist() == [0, 0, 255]


def test_detections_sizes_must_agree() -> None:
    with pytest.raises(TypeValidationError, match="2 boxes, 1 labels and 2 scores"):
        DetectionsMsg(boxes=[[0, 0, 1, 1], [1, 1, 2, 2]], labels=["a"], scores=[0.1, 0.2])
    with pytest.raises(TypeValidationError, match="field 'boxes': expected shape Nx4"):
        DetectionsMsg(boxes=[[0, 0, 1]], labels=["a"], scores=[0.1])


def test_tracking_ids_are_64_bit() -> None:
    ids = TrackingsMsg(ids=[2**62], labels=["x"], boxes=[[0, 0, 1, 1]], centroids=[[0, 0]],
                       estimated_velocities=[[0, 0]]).ids
    assert ids.dtype == np.int64 and int(ids[0]) == 2**62


def test_header_stamp_is_exact_nanoseconds() -> None:
    h = Header(stamp_ns=1_700_000_000_000_000_001, frame_id="map")
    assert h.stamp_ns % 10 == 1
    with pytest.raises(TypeValidationError, match="stamp_ns"):
        Header(stamp_ns=-1)


def test_streaming_string_accepts_plain_text_as_final_chunk() -> None:
    msg = StreamingString.validate("done")
    assert isinstance(msg, StreamingStringMsg) and msg.done and not msg.stream
    assert StreamingString.to_output(msg) == "done"
    assert issubclass(StreamingString, String)


def test_unknown_type_name_lists_close_matches() -> None:
    with pytest.raises(UnknownTypeError, match="did you mean 'Image'"):
        Topic("camera", "Imag")
    with pytest.raises(UnknownTypeError, match="did you mean 'String'"):
        get_type("string")


def test_custom_type_registration() -> None:
    class SemanticLabel(SupportedType):
        value_class = dict

    add_additional_datatypes([SemanticLabel])
    assert Topic("labels", "SemanticLabel").msg_type is SemanticLabel
    add_additional_datatypes([SemanticLabel])  # same class again: fine

    class Other(SupportedType):
        pass

    Other.__name__ = "SemanticLabel"
    with pytest.raises(ConfigError, match="already registered"):
        add_additional_datatypes([Other])
    with pytest.raises(ConfigError, match="not a SupportedType"):
        add_additional_datatypes([int])  # type: ignore[list-item]


@pytest.mark.parametrize("name", ["", "with space", "1starts_with_digit", "a//b", "trailing/", "a-b", "a.b",
                                  "wild/*", "x" * 300, "tok/9bad"])
def test_invalid_topic_names_are_rejected(name: str) -> None:
    with pytest.raises(TopicNameError):
        Topic(name, "String")


@pytest.mark.parametrize("name", ["camera", "/robot/camera/rgb", "a_1/b_2", "_private"])
def test_valid_topic_names(name: str) -> None:
    assert Topic(name, String).name == name


def test_qos_is_validated() -> None:
    assert QoSConfig(depth=1).depth == 1
    with pytest.raises(ConfigError, match="depth"):
        QoSConfig(depth=0)
    with pytest.raises(ValueError, match="reliability"):
        QoSConfig(reliability="sometimes")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="qos_profile"):
        Topic("x", "String", qos_profile={"depth": 3})  # type: ignore[arg-type]


def test_fixed_input_validates_its_value() -> None:
    fixed = FixedInput("prompt", "String", "What do you see?")
    assert fixed.fixed == "What do you see?"
    with pytest.raises(TypeValidationError, match="FixedInput 'prompt'"):
        FixedInput("prompt", "String", 42)


def test_topics_are_hashable_and_compare_by_value() -> None:
    assert Topic("a", "String") == Topic("a", String)
    assert len({Topic("a", "String"), Topic("a", String)}) == 1


# -- arrays whose shape claims more than their data holds, absurd dimensions ---------------------


def test_an_image_view_that_claims_more_pixels_than_it_holds_is_refused() -> None:
    one_pixel = np.zeros((1, 1, 3), np.uint8)
    with pytest.raises(TypeValidationError, match=r"field 'data': shape .* claims more elements than its data holds"):
        ImageMsg(data=np.broadcast_to(one_pixel, (4096, 4096, 3)))
    overlapping = np.lib.stride_tricks.as_strided(np.zeros(16, np.uint8), shape=(8, 8, 3), strides=(1, 1, 1))
    with pytest.raises(TypeValidationError, match="claims more elements"):
        ImageMsg(data=overlapping)
    # Views that do own their elements stay accepted, without a copy.
    pixels = np.zeros((8, 10, 3), np.uint8)
    for view in (pixels[::2, ::-1], pixels[:, :, ::-1], pixels.transpose(1, 0, 2)):
        assert ImageMsg(data=view).data.base is not None


@pytest.mark.parametrize("shape", [(0, 2**40, 3), (2**21, 0, 3), (0, 2**21)])
def test_absurd_image_dimensions_are_refused_even_when_empty(shape: tuple[int, ...]) -> None:
    with pytest.raises(TypeValidationError, match=r"field 'data': .* exceeds MAX_IMAGE_SIDE"):
        ImageMsg(data=np.zeros(shape, np.uint8), encoding="mono8" if len(shape) == 2 else "rgb8")
    assert ImageMsg(data=np.zeros((0, 640, 3), np.uint8)).width == 640  # empty but plausible: fine


def test_array_fields_refuse_absurd_dimensions_and_fake_lengths() -> None:
    with pytest.raises(TypeValidationError, match=r"field 'data': shape .* has a dimension above"):
        OccupancyGridMsg(data=np.zeros((0, 2**33), np.int8))
    with pytest.raises(TypeValidationError, match=r"field 'data': shape .* claims more elements"):
        AudioMsg(data=np.broadcast_to(np.zeros(1, np.int16), (10**9,)))
    with pytest.raises(TypeValidationError, match=r"field 'ranges': shape .* claims more elements"):
        get_type("LaserScan").value_class(ranges=np.broadcast_to(np.float32(1.0), (10**9,)))
    with pytest.raises(TypeValidationError, match="field 'channels': expected an int from 1 to 65535"):
        AudioMsg(data=np.zeros(0, np.int16), channels=2**40)
    with pytest.raises(TypeValidationError, match="field 'sample_rate'"):
        AudioMsg(data=np.zeros(4, np.int16), sample_rate=2**33)
