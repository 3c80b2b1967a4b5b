"""ROS 2 conversions of text: ``std_msgs/String`` and ``agents_interfaces/StreamingString``."""

from __future__ import annotations

from typing import Any

from std_msgs.msg import String as RosString

from agents_core import messages as m

from .base import RosConversion, ai, header_from_ros, header_to_ros
from .scalars import scalar

__all__ = ["CONVERSIONS"]


def _streaming_to_ros(v: m.StreamingStringMsg) -> Any:
    out = ai.StreamingString(data=v.data, stream=v.stream, done=v.done)
    header_to_ros(v.header, out.header)
    return out


def _streaming_from_ros(msg: Any) -> m.StreamingStringMsg:
    return m.StreamingStringMsg(data=msg.data, stream=msg.stream, done=msg.done, header=header_from_ros(msg.header))


#: The built-in conversions of this family.
CONVERSIONS: dict[str, RosConversion] = {
    "String": scalar(RosString, str),
    "StreamingString": RosConversion(ai.StreamingString, _streaming_to_ros, _streaming_from_ros),
}
