"""ROS 2 CDR for recordings: a value's bytes as ``ros2 bag`` stores them, and its message definition.

:mod:`agents_core.recording` loads this module by name (the core never imports rclpy) to write the
types that have a ROS 2 conversion as ``cdr`` messages with a ``ros2msg`` schema, the form
``ros2 bag``, ``rosbags`` and Foxglove read. The definition text is built from the generated
message class (its field table), not from ``share/<pkg>/msg/*.msg``, so it needs no sourced ROS
environment: the main type's fields, then each nested type once, after a line of ``=`` and
``MSG: pkg/Type`` (the layout ``ros2 bag`` writes).
"""

from __future__ import annotations

import importlib
import re
import warnings
from collections.abc import Callable
from typing import Any

from agents_core.supported_types import SupportedType, registered_types

from .conversions import conversion_for, registered_conversions

__all__ = ["cdr_codec", "message_definition", "ros_type_name", "type_for_ros_name"]

#: IDL primitive names (what rosidl's field table says) -> .msg names.
_PRIMITIVES = {"float": "float32", "double": "float64", "boolean": "bool", "octet": "byte", "long double": "float64"}
_SEPARATOR = "=" * 80


def ros_type_name(ros_type: type[Any]) -> str:
    """``sensor_msgs/msg/Image`` for the generated class ``sensor_msgs.msg.Image``."""
    return f"{ros_type.__module__.split('.')[0]}/msg/{ros_type.__name__}"


def _msg_field(idl: str) -> tuple[str, str | None]:
    """(the .msg spelling of an IDL field type, the nested ``pkg/Type`` it names or None)."""
    if (seq := re.fullmatch(r"sequence<(.+?)(?:, (\d+))?>", idl)) is not None:
        inner, nested = _msg_field(seq.group(1))
        return (f"{inner}[<={seq.group(2)}]" if seq.group(2) else f"{inner}[]"), nested
    if (arr := re.fullmatch(r"(.+)\[(\d+)\]", idl)) is not None:
        inner, nested = _msg_field(arr.group(1))
        return f"{inner}[{arr.group(2)}]", nested
    if (bounded := re.fullmatch(r"(w?string)<(\d+)>", idl)) is not None:
        return f"{bounded.group(1)}<={bounded.group(2)}", None
    if "/" in idl:
        return idl, idl
    return _PRIMITIVES.get(idl, idl), None


def _message_class(nested: str) -> type[Any]:
    package, _, name = nested.partition("/")
    return getattr(importlib.import_module(f"{package}.msg"), name.rpartition("/")[2])  # type: ignore[no-any-return]


def message_definition(ros_type: type[Any]) -> str:
    """The ``ros2msg`` definition of ``ros_type`` with its nested types (each once)."""
    sections: list[str] = []
    seen: set[str] = set()
    pending: list[tuple[str | None, type[Any]]] = [(None, ros_type)]
    while pending:
        name, cls = pending.pop(0)
        lines = []
        for field_name, idl in cls.get_fields_and_field_types().items():
            spelled, nested = _msg_field(idl)
            lines.append(f"{spelled} {field_name}")
            if nested is not None and nested not in seen:
                seen.add(nested)
                pending.append((nested, _message_class(nested)))
        body = "\n".join(lines) + "\n"
        sections.append(body if name is None else f"{_SEPARATOR}\nMSG: {name}\n{body}")
    return "".join(sections)


def cdr_codec(msg_type: type[SupportedType]) -> tuple[str, str, Callable[[Any], bytes], Callable[[bytes], Any]]:
    """(ROS type name, its definition, value -> CDR bytes, CDR bytes -> value) for ``msg_type``.

    Raises :class:`~agents_ros2.conversions.MissingConversionError` for a type with no ROS form.
    """
    with warnings.catch_warnings():
        # rosidl's parser imports lark, which imports the deprecated sre_parse (see agents_ros2.conversions).
        warnings.simplefilter("ignore", DeprecationWarning)
        from rclpy.serialization import deserialize_message, serialize_message  # noqa: PLC0415

    conversion = conversion_for(msg_type)
    ros_type = conversion.ros_type
    validate, to_ros, from_ros = msg_type.validate, conversion.to_ros, conversion.from_ros

    def encode(value: Any) -> bytes:
        return serialize_message(to_ros(validate(value)))  # type: ignore[no-any-return]

    def decode(data: bytes) -> Any:
        return from_ros(deserialize_message(data, ros_type))

    return ros_type_name(ros_type), message_definition(ros_type), encode, decode


def type_for_ros_name(schema_name: str) -> type[SupportedType] | None:
    """The agents_core type that travels as ROS type ``schema_name`` (``sensor_msgs/msg/Image``), if one does."""
    types = registered_types()
    for type_name, conversion in registered_conversions().items():
        if ros_type_name(conversion.ros_type) == schema_name and type_name in types:
            return types[type_name]
    return None
