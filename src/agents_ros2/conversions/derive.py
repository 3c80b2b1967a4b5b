"""ROS 2 conversions derived from a type's ``_ros_type``: the message itself, or an attrs value class field by field."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import attrs
import numpy as np

from agents_core.errors import ConfigError, TypeValidationError
from agents_core.supported_types import SupportedType, ros_message_class

from .base import RosConversion, as_numpy, duration_from_ros, duration_to_ros, f32, header_from_ros, header_to_ros, seq
from .media import optional_image_from_ros, optional_image_to_ros

__all__ = ["derive_conversion"]


_ROS_TYPECODES: dict[str, tuple[str, type[np.generic]]] = {
    "float": ("f", np.float32), "double": ("d", np.float64), "int8": ("b", np.int8), "uint8": ("B", np.uint8),
    "int16": ("h", np.int16), "uint16": ("H", np.uint16), "int32": ("i", np.int32), "uint32": ("I", np.uint32),
    "int64": ("q", np.int64), "uint64": ("Q", np.uint64),
}


def derive_conversion(msg_type: type[SupportedType]) -> RosConversion:
    """The conversion of a type that names its ROS message in ``_ros_type``.

    A type without a value class of its own (the upstream way) uses the ROS message as its value:
    the conversion is the identity. An attrs value class is copied field by field into the
    message's fields of the same names: a :class:`~agents_core.messages.Header` into
    ``std_msgs/Header`` (stamp exact to the nanosecond), a nested value through its own type's
    conversion (an ``ImageMsg`` as ``sensor_msgs/Image``, ``None`` as an empty one), numpy arrays
    as numeric sequences, ``float`` seconds as ``builtin_interfaces/Duration``, the rest as is.
    Raises :class:`ConfigError` naming the package to install, or the field that has no counterpart.
    """
    ros_type = ros_message_class(msg_type)
    if msg_type.value_class is object:
        return RosConversion(ros_type, lambda v: v, lambda msg: msg)
    value_class = msg_type.value_class
    if not attrs.has(value_class):
        raise ConfigError(f"{msg_type.type_name()}: a _ros_type conversion needs an attrs value class or none, "
                          f"not {value_class.__name__}; register one with register_conversion()")
    ros_fields: dict[str, str] = ros_type.get_fields_and_field_types()
    copies = []
    for f in attrs.fields(value_class):
        if not f.init:
            continue
        if f.name not in ros_fields:
            raise ConfigError(f"{msg_type.type_name()}: field {f.name!r} of {value_class.__name__} has no field "
                              f"of that name in {ros_type.__module__.split('.')[0]}/{ros_type.__name__} "
                              f"(it has {sorted(ros_fields)})")
        copies.append(_field_copy(f, ros_fields[f.name]))

    def to(value: Any) -> Any:
        out = ros_type()
        for name, write, _ in copies:
            try:
                write(getattr(value, name), out, name)
            except TypeValidationError as exc:
                raise TypeValidationError(f"{msg_type.type_name()} field {name!r}: {exc}") from exc
        return out

    def back(message: Any) -> Any:
        kwargs = {}
        for name, _, read in copies:
            try:
                kwargs[name] = read(getattr(message, name))
            except TypeValidationError as exc:
                raise TypeValidationError(f"{msg_type.type_name()} field {name!r}: {exc}") from exc
        return value_class(**kwargs)

    return RosConversion(ros_type, to, back)


_Write = Callable[[Any, Any, str], None]
_Read = Callable[[Any], Any]


def _field_copy(f: attrs.Attribute[Any], ros_kind: str) -> tuple[str, _Write, _Read]:
    """How one value-class field is written into, and read from, the ROS field of the same name."""
    def assign(value: Any, out: Any, name: str) -> None:
        setattr(out, name, value)

    def header(value: Any, out: Any, name: str) -> None:
        header_to_ros(value, getattr(out, name))

    if ros_kind == "std_msgs/Header":
        return f.name, header, header_from_ros
    if ros_kind == "builtin_interfaces/Duration":
        return f.name, lambda v, out, name: setattr(out, name, duration_to_ros(v)), duration_from_ros
    if ros_kind == "sensor_msgs/Image":
        return (f.name, lambda v, out, name: optional_image_to_ros(v, getattr(out, name)),
                optional_image_from_ros)
    sequence = ros_kind.removeprefix("sequence<").removesuffix(">") if ros_kind.startswith("sequence<") else None
    if sequence in _ROS_TYPECODES:
        typecode, dtype = _ROS_TYPECODES[sequence]
        default: Any = f.default
        template = default.factory() if isinstance(default, attrs.Factory) else None  # type: ignore[arg-type]
        tail = tuple(template.shape[1:]) if isinstance(template, np.ndarray) else ()

        def read(values: Any) -> Any:
            flat = as_numpy(values, dtype)
            return flat.reshape(-1, *tail) if tail else flat

        return (f.name, lambda v, out, name: setattr(out, name, seq(typecode, np.asarray(v).reshape(-1), dtype)),
                read)
    if ros_kind == "float":
        return f.name, assign, f32
    if ros_kind == "sequence<string>":
        return f.name, lambda v, out, name: setattr(out, name, list(v)), list
    return f.name, assign, lambda v: v
