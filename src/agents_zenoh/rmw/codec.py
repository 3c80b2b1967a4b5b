"""A message type's codec on rmw_zenoh: the ``ros2`` transport's conversion, then CDR by :mod:`.typesupport`.

One set of conversions: a value goes through :func:`agents_ros2.conversions.conversion_for`'s
``to_ros`` (a message object of the type's ROS message class) and is written as CDR; received CDR
is read as a ``rosbags`` dataclass with the same field names, which the conversion's ``from_ros``
reads as it reads an rclpy message.
"""

from __future__ import annotations

import array
from typing import Any

from attrs import define

from agents_core.supported_types import SupportedType

from .typesupport import RosTypes, ros_type_name, ros_types
from .wire import dds_type_name

__all__ = ["RmwCodec", "codec_for"]


@define(frozen=True)
class RmwCodec:
    """How one message type is written and read on rmw_zenoh."""

    msg_type: type[SupportedType]
    #: ``pkg/msg/Type``.
    ros_type: str
    #: ``RIHS01_<hex>`` of the ROS type.
    type_hash: str
    _to_ros: Any
    _from_ros: Any
    _types: RosTypes

    @property
    def dds_type(self) -> str:
        """The type as rmw_zenoh writes it in keys and tokens (``pkg::msg::dds_::Type_``)."""
        return dds_type_name(self.ros_type)

    def encode(self, value: Any) -> bytes:
        """A value (validated by the core) as CDR bytes."""
        return self._types.serialize(self._to_ros(value), self.ros_type)

    def encode_into(self, value: Any, buffer: bytearray | None) -> bytearray:
        """:meth:`encode` into ``buffer`` when it has the size, else into a new one (see ``serialize_into``)."""
        return self._types.serialize_into(self._to_ros(value), self.ros_type, buffer)

    def decode(self, data: bytes | bytearray | memoryview) -> Any:
        """CDR bytes as a validated value (TypeValidationError with the reason)."""
        return self._from_ros(self._types.deserialize(data, self.ros_type))


def as_class(message: Any, cls: type[Any]) -> Any:
    """A received (rosbags) message as an instance of ``cls`` (an rclpy message class), field by field."""
    if isinstance(message, cls):
        return message
    out = cls()
    for name in cls.get_fields_and_field_types():
        value = getattr(message, name)
        current = getattr(out, name)
        if hasattr(type(current), "get_fields_and_field_types"):
            value = as_class(value, type(current))
        elif isinstance(current, array.array) and hasattr(value, "tobytes"):
            converted = array.array(current.typecode)
            converted.frombytes(value.tobytes())  # the same element type on both sides
            value = converted
        elif isinstance(value, list) and value and hasattr(value[0], "__msgtype__"):
            item_cls = _item_class(cls, name)
            value = [as_class(v, item_cls) for v in value] if item_cls is not None else value
        setattr(out, name, value)
    return out


def _item_class(cls: type[Any], field: str) -> type[Any] | None:
    """The message class of the items of a sequence field of an rclpy class (from its SLOT_TYPES)."""
    import importlib  # noqa: PLC0415

    index = list(cls.get_fields_and_field_types()).index(field)
    slot = cls.SLOT_TYPES[index]
    value_type = getattr(slot, "value_type", None)
    namespaces = getattr(value_type, "namespaces", None)
    if value_type is None or not namespaces:
        return None
    item: type[Any] = getattr(importlib.import_module(".".join(namespaces)), value_type.name)
    return item


_codecs: dict[str, RmwCodec] = {}


def codec_for(msg_type: type[SupportedType]) -> RmwCodec:
    """The codec of ``msg_type`` (MissingConversionError when it has no ROS 2 conversion)."""
    name = msg_type.type_name()
    found = _codecs.get(name)
    if found is not None and found.msg_type is msg_type:
        return found
    from agents_ros2.conversions import conversion_for  # noqa: PLC0415  # ROS message classes: only when used

    conversion = conversion_for(msg_type)
    types = ros_types()
    ros_type = ros_type_name(conversion.ros_type)
    from_ros = conversion.from_ros
    if msg_type.value_class is object:
        # The upstream way: the value is the ROS message itself, so a received one is given as that class too.
        cls = conversion.ros_type

        def from_ros(message: Any) -> Any:
            return msg_type.validate(as_class(message, cls))

    codec = RmwCodec(msg_type, ros_type, types.type_hash(ros_type), conversion.to_ros, from_ros, types)
    _codecs[name] = codec
    return codec
