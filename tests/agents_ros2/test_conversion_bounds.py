"""ROS 2 conversions of malformed messages: a value or a TypeValidationError, never a crash or a huge allocation.

rclpy deserializes CDR itself (bounded by the message definition), so what a hostile or buggy
ROS 2 publisher controls is the *fields*: an Image whose height x step does not match its data,
absurd widths, a multi-array layout whose dimensions multiply past its data, a header with 2**32
nanoseconds, a video whose frame order lies. Hypothesis (derandomized) mutates the ROS message
of every built-in type, field by field, and checks ``from_ros``.
"""

from __future__ import annotations

import importlib
import tracemalloc
from typing import Any

import numpy as np
import pytest

pytest.importorskip("rclpy", reason="needs the ros2 extra")
pytest.importorskip("agents_interfaces", reason="needs agents_interfaces (pip install --no-build-isolation "
                                                "./interfaces)")
pytest.importorskip("hypothesis")

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Image as RosImage
from std_msgs.msg import Float64MultiArray as RosFloat64MultiArray
from std_msgs.msg import MultiArrayDimension

from agents_core import messages as m
from agents_core.errors import TypeValidationError
from agents_core.supported_types import SupportedType, get_type, registered_types
from agents_core.types import is_builtin_type
from agents_ros2.conversions import from_ros, to_ros

pytestmark = pytest.mark.ros2

#: Peak traced memory of one conversion <= BOUND_FACTOR x the message's CDR size + BOUND_SLACK.
#: Conversions are zero-copy or copy once (padded image rows, byte-swapped pixels): 4x measured.
BOUND_FACTOR = 16
BOUND_SLACK = 2 * 1024 * 1024

_PROFILE = settings(deadline=None, derandomize=True, database=None, print_blob=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

TYPES: dict[str, type[SupportedType]] = {n: t for n, t in registered_types().items() if is_builtin_type(t)}
TYPE_NAMES = sorted(TYPES)

_INTS = {"uint8": (0, 2**8 - 1), "int8": (-(2**7), 2**7 - 1), "uint16": (0, 2**16 - 1), "int16": (-(2**15), 2**15 - 1),
         "uint32": (0, 2**32 - 1), "int32": (-(2**31), 2**31 - 1), "uint64": (0, 2**64 - 1),
         "int64": (-(2**63), 2**63 - 1)}
_STRINGS = st.text(max_size=12) | st.sampled_from([*m.IMAGE_ENCODINGS, "yuv422", "S16LE", "F32LE", "", "jpeg"])


def _ints(kind: str) -> st.SearchStrategy[int]:
    lo, hi = _INTS[kind]
    # The edges and small values are where size arithmetic goes wrong; a uniform draw rarely finds them.
    edges = sorted({lo, hi, 0, 1, 2, 3, 4, hi // 2, min(hi, 2**31), min(hi, 2**20 + 1)})
    return st.sampled_from(edges) | st.integers(lo, hi)


def _primitive(kind: str) -> st.SearchStrategy[Any] | None:
    if kind in _INTS:
        return _ints(kind)
    if kind in ("float", "double"):
        return st.floats(width=32 if kind == "float" else 64)
    if kind == "boolean":
        return st.booleans()
    if kind == "string":
        return _STRINGS
    return None  # octet, char, wstring, fixed-size arrays: left as they are


def _message_class(kind: str) -> Any:
    package, name = kind.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def _leaves(msg: Any) -> list[tuple[Any, str, str]]:
    """Every (owner, field, type) that can be mutated, nested messages and sequence items included."""
    found: list[tuple[Any, str, str]] = []
    for name, kind in type(msg).get_fields_and_field_types().items():
        if "/" in kind and not kind.startswith("sequence<"):
            found.extend(_leaves(getattr(msg, name)))
            continue
        found.append((msg, name, kind))
        if kind.startswith("sequence<") and "/" in kind:
            for item in getattr(msg, name):
                found.extend(_leaves(item))
    return found


@st.composite
def _mutate(draw: st.DrawFn, msg: Any) -> Any:
    """``msg`` with one to four fields replaced by values of the right ROS type but arbitrary content."""
    for _ in range(draw(st.integers(1, 4))):
        owner, name, kind = draw(st.sampled_from(_leaves(msg)))
        if kind.startswith("sequence<"):
            inner = kind[len("sequence<"):-1].split(",")[0]
            if "/" in inner:
                items = list(getattr(owner, name))
                cls = _message_class(inner)
                size = draw(st.integers(0, 4))
                value: Any = [items[i % len(items)] if items else cls() for i in range(size)]
            elif inner == "uint8":
                value = draw(st.binary(max_size=256))
            else:
                strategy = _primitive(inner)
                if strategy is None:
                    continue
                value = draw(st.lists(strategy, max_size=16))
        else:
            strategy = _primitive(kind)
            if strategy is None:
                continue
            value = draw(strategy)
        setattr(owner, name, value)
    return msg


def _convert_within_bounds(type_name: str, message: Any) -> str:
    """``from_ros``: "ok" (and the value validates) or "refused" (TypeValidationError); anything else fails."""
    try:
        size = len(serialize_message(message))
    except Exception:  # a value rclpy cannot serialize (e.g. a lone surrogate) still converts
        size = 0
    tracemalloc.start()
    try:
        try:
            value = from_ros(TYPES[type_name], message)
            TYPES[type_name].validate(value)
            outcome = "ok"
        except TypeValidationError:
            outcome = "refused"
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    bound = BOUND_FACTOR * size + BOUND_SLACK
    assert peak <= bound, f"{type_name}: converting a {size}-byte message peaked at {peak} traced bytes"
    return outcome


@settings(_PROFILE, max_examples=600)
@given(data=st.data(), type_name=st.sampled_from(TYPE_NAMES))
def test_mutated_messages_convert_or_are_refused(data: st.DataObject, type_name: str) -> None:
    msg_type = TYPES[type_name]
    message = to_ros(msg_type, msg_type.example())
    _convert_within_bounds(type_name, data.draw(_mutate(message)))


@settings(_PROFILE, max_examples=400)
@given(encoding=st.sampled_from([*m.IMAGE_ENCODINGS, "yuv422"]), height=_ints("uint32"), width=_ints("uint32"),
       step=_ints("uint32"), data=st.binary(max_size=512), big_endian=st.booleans())
def test_images_with_inconsistent_fields_are_refused_before_any_allocation(
    encoding: str, height: int, width: int, step: int, data: bytes, big_endian: bool,
) -> None:
    message = RosImage(encoding=encoding, height=height, width=width, step=step, data=data,
                       is_bigendian=int(big_endian))
    if _convert_within_bounds("Image", message) == "ok":
        image = from_ros(get_type("Image"), message)
        dtype, channels = m.IMAGE_ENCODINGS[encoding]
        assert image.data.shape == (height, width, channels) and image.data.dtype == dtype
        assert height * step == len(data) and step >= width * channels * np.dtype(dtype).itemsize


@settings(_PROFILE, max_examples=200)
@given(sizes=st.lists(_ints("uint32"), max_size=40), offset=_ints("uint32"),
       values=st.lists(st.floats(), max_size=32))
def test_multi_array_layouts_that_lie_are_refused(sizes: list[int], offset: int, values: list[float]) -> None:
    message = RosFloat64MultiArray(data=values)
    message.layout.data_offset = offset
    message.layout.dim = [MultiArrayDimension(label=f"d{i}", size=s, stride=0) for i, s in enumerate(sizes)]
    if _convert_within_bounds("Float64MultiArray", message) == "ok":
        array = from_ros(get_type("Float64MultiArray"), message)
        assert array.size == max(0, len(values) - offset)


@pytest.mark.parametrize(("fields", "reason"), [
    ({"height": 0, "width": 2**32 - 1, "step": 2**32 - 1, "data": b""}, "exceeds MAX_IMAGE_SIDE"),
    ({"height": 2**21, "width": 0, "step": 0, "data": b""}, "exceeds MAX_IMAGE_SIDE"),
    ({"height": 2**31, "width": 2, "step": 6, "data": bytes(12)}, "exceeds MAX_IMAGE_SIDE"),
    ({"height": 2, "width": 2, "step": 2**31, "data": bytes(12)}, "image data has 12 bytes"),
    ({"height": 4, "width": 4, "step": 12, "data": bytes(47)}, "image data has 47 bytes"),
])
def test_images_whose_size_lies_are_refused_with_the_reason(fields: dict[str, Any], reason: str) -> None:
    with pytest.raises(TypeValidationError, match=reason):
        from_ros(get_type("Image"), RosImage(encoding="rgb8", **fields))


def test_lying_layouts_and_headers_are_refused_with_the_reason() -> None:
    deep = RosFloat64MultiArray(data=[1.0])
    deep.layout.dim = [MultiArrayDimension(size=1) for _ in range(70)]  # numpy itself stops at 64
    with pytest.raises(TypeValidationError, match="70 dimensions"):
        from_ros(get_type("Float64MultiArray"), deep)
    wide = RosFloat64MultiArray(data=[1.0, 2.0])
    wide.layout.dim = [MultiArrayDimension(size=2**32 - 1) for _ in range(3)]  # 2**96: never wraps to 2
    with pytest.raises(TypeValidationError, match="needs"):
        from_ros(get_type("Float64MultiArray"), wide)
    image = to_ros(get_type("Image"), get_type("Image").example())
    image.header.stamp.nanosec = 2**32 - 1
    with pytest.raises(TypeValidationError, match="nanoseconds"):
        from_ros(get_type("Image"), image)
    audio = to_ros(get_type("Audio"), get_type("Audio").example())
    audio.channels = 0
    with pytest.raises(TypeValidationError, match="channels"):
        from_ros(get_type("Audio"), audio)
