"""The table of ROS 2 conversions: one :class:`~agents_ros2.conversions.base.RosConversion` per message type.

Looked up by type name; a type without an entry gets one derived from its ``_ros_type``
(:mod:`~agents_ros2.conversions.derive`) or its nearest registered base's.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import attrs
import numpy as np

from agents_core.support.registry import NotRegisteredError, Registry
from agents_core.supported_types import SupportedType, get_type, shares_value_class

from .base import RosConversion
from .derive import derive_conversion

__all__ = [
    "MissingConversionError",
    "conversion_for",
    "from_ros",
    "register_builtin",
    "register_conversion",
    "registered_conversions",
    "to_ros",
]


class MissingConversionError(NotRegisteredError):
    """A message type has no ROS 2 conversion (none registered, no ``_ros_type`` to derive one from)."""


_conversions: Registry[RosConversion] = Registry(
    "ROS 2 conversion", missing_error=MissingConversionError, missing_text="message type {name} has no {kind}",
    class_name=lambda cls: cls.type_name() if issubclass(cls, SupportedType) else cls.__name__,
    hint="register one with agents_ros2.conversions.register_conversion(), or give the type a _ros_type",
)


def register_conversion(
    msg_type: str | type[SupportedType],
    ros_type: type[Any],
    to_ros: Callable[[Any], Any],
    from_ros: Callable[[Any], Any],
) -> None:
    """Register how the message type ``msg_type`` (a SupportedType or its name) travels on ROS 2.

    Registering again for the same name replaces the conversion (a deliberate override).
    """
    name = get_type(msg_type).type_name()
    _conversions.register(name, RosConversion(ros_type, to_ros, from_ros), replace=True)


def registered_conversions() -> dict[str, RosConversion]:
    """A snapshot: type name -> conversion."""
    return _conversions.snapshot()


def conversion_for(msg_type: type[SupportedType]) -> RosConversion:
    """The conversion for ``msg_type``: its own, one derived from its ``_ros_type``, or its nearest base's.

    A type that declares a ``_ros_type`` of its own travels as that message: a type whose value is
    the ROS message itself (the upstream way) as is, an attrs value class field by field (see
    :func:`derive_conversion`). A subclass of a registered type with the same value class
    (``class MyImage(Image)``) uses its base's conversion: the registries' one subclass rule.
    """
    name = msg_type.type_name()
    own = _conversions.find(name)
    if own is not None:
        return own
    if "_ros_type" in vars(msg_type) and msg_type._ros_type is not None:
        return _conversions.register(name, derive_conversion(msg_type))
    found = _conversions.find_for_class(msg_type, inherits=shares_value_class)
    if found is not None:
        return found
    raise _conversions.missing(name)


def to_ros(msg_type: type[SupportedType], value: Any) -> Any:
    """Validate ``value`` as ``msg_type`` and convert it to its ROS message."""
    return conversion_for(msg_type).to_ros(msg_type.validate(value))


def from_ros(msg_type: type[SupportedType], message: Any) -> Any:
    """Convert a received ROS message to the value of ``msg_type`` (raises TypeValidationError)."""
    return conversion_for(msg_type).from_ros(message)


def _overflow_to_inf(from_ros: Callable[[Any], Any]) -> Callable[[Any], Any]:
    """``from_ros`` where a float beyond float32's range becomes inf, as a C cast would, without a warning.

    rclpy accepts such a value in a float32 field of a message built in Python (its range check is
    looser than float32's), and numpy warns when casting it: that must not fail the conversion.
    """
    def convert(message: Any) -> Any:
        with np.errstate(over="ignore"):
            return from_ros(message)

    return convert


def register_builtin(table: Mapping[str, RosConversion]) -> None:
    """Register one family's built-in conversions in the table's order, each ``from_ros`` wrapped by
    :func:`_overflow_to_inf`."""
    for name, c in table.items():
        _conversions.register(name, attrs.evolve(c, from_ros=_overflow_to_inf(c.from_ros)))
