"""What every family of ROS 2 conversions shares: the :class:`RosConversion` record and the field building blocks.

Headers (``Header.stamp_ns`` <-> ``stamp.sec`` / ``stamp.nanosec`` exactly, with the bounds of ROS 2
time), durations, numeric sequences (``array.array`` out, zero-copy numpy in) and float32 fields
read back as their shortest decimal. Importing this module also imports ``agents_interfaces``
(the framework's own messages, :data:`ai`) with a helpful error where it is missing.
"""

from __future__ import annotations

import array
import sys
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt
from attrs import define
from builtin_interfaces.msg import Duration as RosDuration
from std_msgs.msg import Header as RosHeader

from agents_core import messages as m
from agents_core.errors import TypeValidationError

with warnings.catch_warnings():
    # rclpy imports rosidl_generator_py the first time it loads a type support, which imports the
    # old lark-parser that rosidl pins, which imports the deprecated sre_parse. Importing it here,
    # once, keeps that DeprecationWarning out of user code (and out of filterwarnings=error runs).
    warnings.simplefilter("ignore", DeprecationWarning)
    import rosidl_generator_py  # noqa: F401

try:
    from agents_interfaces import msg as ai
except ImportError as exc:  # pragma: no cover - depends on the installation
    raise ImportError(
        f"the ROS 2 interface package agents_interfaces is not installed ({exc}); build it into this "
        "environment with: pip install --no-build-isolation ./interfaces (see docs/ros2.md)"
    ) from exc

__all__ = [
    "INT32_MAX",
    "NATIVE_BIG_ENDIAN",
    "NS_PER_S",
    "RosConversion",
    "ai",
    "as_numpy",
    "duration_from_ros",
    "duration_to_ros",
    "f32",
    "header_from_ros",
    "header_to_ros",
    "seq",
]


NS_PER_S = 1_000_000_000
INT32_MAX = 2**31 - 1
NATIVE_BIG_ENDIAN = sys.byteorder == "big"


@define(frozen=True)
class RosConversion:
    """How one message type travels on ROS 2."""

    #: The ROS message class (e.g. ``sensor_msgs.msg.Image``).
    ros_type: type[Any]
    #: Value (already validated by the SupportedType) -> ROS message.
    to_ros: Callable[[Any], Any]
    #: ROS message -> value; raises TypeValidationError with the reason when it has no value form.
    from_ros: Callable[[Any], Any]


def header_to_ros(header: m.Header, out: RosHeader) -> RosHeader:
    """Write ``header`` into the ROS header ``out``, stamp exact; TypeValidationError past int32 seconds."""
    sec, nanosec = divmod(int(header.stamp_ns), NS_PER_S)
    if sec > INT32_MAX:
        raise TypeValidationError(f"header stamp {header.stamp_ns} ns does not fit ROS 2 time (int32 seconds)")
    out.stamp.sec = sec
    out.stamp.nanosec = nanosec
    out.frame_id = header.frame_id
    return out


def header_from_ros(header: RosHeader) -> m.Header:
    """A received ROS header as a :class:`~agents_core.messages.Header`; TypeValidationError for an invalid stamp."""
    if header.stamp.sec < 0:
        raise TypeValidationError(f"header stamp has negative seconds ({header.stamp.sec})")
    if header.stamp.nanosec >= NS_PER_S:
        raise TypeValidationError(f"header stamp has {header.stamp.nanosec} nanoseconds (must be below 1e9)")
    return m.Header(stamp_ns=header.stamp.sec * NS_PER_S + header.stamp.nanosec, frame_id=header.frame_id)


def seq(typecode: str, values: npt.ArrayLike, dtype: type[np.generic]) -> array.array[Any]:
    """A numeric ROS sequence field: rclpy takes an ``array.array`` of the field's type without a per-item check."""
    data = np.ascontiguousarray(values, dtype=dtype)
    received = _received_sequence(data, typecode)
    if received is not None:
        return received
    out = array.array(typecode)
    # frombytes reads the array's buffer directly: one copy of the data (tobytes() would add one).
    out.frombytes(data.data.cast("B"))
    return out


def _received_sequence(data: npt.NDArray[Any], typecode: str) -> array.array[Any] | None:
    """The ``array.array`` of a received ROS message that ``data`` views whole, else None.

    A value decoded from a ROS message views its sequence without a copy (:func:`as_numpy`); when
    a component publishes it again unchanged (a relay, a filter that passes frames on), its
    ``array.array`` is sent as it is instead of being copied (~0.9 MB for a 640x480 image).
    rclpy only reads a message's sequences when it publishes.
    """
    base: Any = data
    while isinstance(base, np.ndarray):
        base = base.base
    source = base.obj if isinstance(base, memoryview) else None
    if (not isinstance(source, array.array) or source.typecode != typecode
            or data.nbytes != len(source) * source.itemsize or not data.nbytes):
        return None
    # Same bytes: the view starts where the array's buffer starts and covers all of it.
    return source if data.__array_interface__["data"][0] == source.buffer_info()[0] else None


def as_numpy(values: Any, dtype: type[np.generic]) -> npt.NDArray[Any]:
    """A received numeric sequence as numpy (zero-copy over rclpy's ``array.array`` of the same type)."""
    if isinstance(values, array.array) and np.dtype(dtype).itemsize == values.itemsize:
        return np.frombuffer(values, dtype=dtype)
    if isinstance(values, bytes):
        return np.frombuffer(values, dtype=dtype)
    return np.asarray(values, dtype=dtype)


def f32(value: float) -> float:
    """A float32 field read back as the shortest decimal that rounds to it (0.1f -> 0.1, not 0.100000001)."""
    return float(str(np.float32(value)))


def duration_to_ros(seconds: float) -> RosDuration:
    """``seconds`` as ``builtin_interfaces/Duration``; TypeValidationError where it does not fit."""
    total = round(seconds * NS_PER_S)
    sec, nanosec = divmod(total, NS_PER_S)
    if not -(2**31) <= sec <= INT32_MAX:
        raise TypeValidationError(f"duration {seconds} s does not fit ROS 2 Duration")
    return RosDuration(sec=sec, nanosec=nanosec)


def duration_from_ros(d: RosDuration) -> float:
    """A ``builtin_interfaces/Duration`` as float seconds."""
    return float(d.sec + d.nanosec / NS_PER_S)
