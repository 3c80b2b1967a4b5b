"""The base of every message type: :class:`SupportedType`, the registry of types, and the ROS-message checks.

A :class:`SupportedType` subclass is a *type token*: it is what ``Topic(msg_type=...)`` names and
what ``allowed_inputs`` lists. It is never instantiated. It says which Python values it accepts
(:meth:`SupportedType.validate`, which also normalises convenient forms such as a bare numpy
array for an Image) and what a component's callback hands to ``_execution_step``
(:meth:`SupportedType.to_output`). Transport adapters keep their own codec per type name.

Types are looked up by name through the registry; :func:`add_additional_datatypes` registers
user-defined ones so that ``Topic(msg_type="MyType")`` resolves everywhere. The built-in types
live in the family modules of :mod:`agents_core.types`, which registers them at the registry's first
use (:func:`install_builtin_types`); this module imports none of them.
"""

from __future__ import annotations

import array
import importlib
import math
import threading
from collections.abc import Callable, Iterable
from typing import Any, ClassVar

from ..errors import ConfigError, TypeValidationError, UnknownTypeError
from ..support.lazy_numpy import is_ndarray, is_np_bool, is_np_integer, is_np_number
from ..support.registry import DuplicateNameError, Registry

__all__ = [
    "SupportedType",
    "add_additional_datatypes",
    "check_convertible",
    "check_ros_message",
    "convert_published",
    "get_type",
    "install_builtin_types",
    "registered_types",
    "ros_message_class",
    "shares_value_class",
]


class _DefaultCallback:
    """``SupportedType.callback`` of a type that names none: :class:`~agents_core.callbacks.GenericCallback`.

    messages.md: "Each ``SupportedType.callback`` class inherits from ``GenericCallback``", so
    ``String.callback`` is a class, as upstream. A descriptor, since the callbacks module imports the
    topics, which import this one.
    """

    def __get__(self, instance: object, owner: type | None = None) -> type[Any]:
        from ..callbacks import GenericCallback  # noqa: PLC0415 - see the class docstring

        return GenericCallback


class SupportedType:
    """Base of every message type token.

    Subclasses set :attr:`value_class` (the Python class of a validated value) and override
    :meth:`validate` when they accept more than instances of it. Subclassing an existing type
    makes the new one acceptable wherever the parent is allowed (``StreamingString`` passes where
    ``String`` is required).

    The upstream extension hooks (messages.md, custom_component.md) work as written there:

    - ``_ros_type``: the ROS message class (or its name, ``"pkg/msg/Name"``) the type travels as
      on ROS 2. A type with a ``_ros_type`` and no :attr:`value_class` of its own uses the ROS
      message itself as its value, on every transport (Zenoh sends its fields as a msgpack map).
    - ``convert(output, **kwargs)``: turns what a component publishes (a dict, an array, ...)
      into the type's value; :meth:`validate` calls it for anything that is not a value already.
    - ``callback``: the :class:`~agents_core.callbacks.GenericCallback` subclass that components
      create for inputs of this type; its ``_msg_to_output`` / ``_get_output`` give ``get_output()``.
    """

    value_class: ClassVar[type[Any]] = object
    #: The ROS message class (or ``"pkg/msg/Name"``) this type travels as on ROS 2 (None: the adapter's table).
    _ros_type: ClassVar[Any] = None
    #: The callback class components create for inputs of this type (GenericCallback unless a type names its own).
    callback: ClassVar[Any] = _DefaultCallback()

    @classmethod
    def type_name(cls) -> str:
        """The registry name (the class name)."""
        return cls.__name__

    @classmethod
    def message_class(cls) -> type[Any]:
        """The class of this type's values: :attr:`value_class`, else the ROS message of ``_ros_type``."""
        if cls.value_class is object and cls._ros_type is not None:
            return ros_message_class(cls)
        return cls.value_class

    @classmethod
    def validate(cls, value: Any) -> Any:
        """Return ``value`` in this type's canonical form, or raise :class:`TypeValidationError`."""
        message_class = cls.message_class()
        if not isinstance(value, message_class) and _overrides_convert(cls):
            value = _converted(cls, value, message_class)
        if isinstance(value, message_class):
            if message_class is not cls.value_class:
                # A ROS message (rosidl checks field types only with ROS_PYTHON_CHECK_FIELDS=1): check it here,
                # so that a bad field fails on publish, naming it, on every transport.
                check_ros_message(value, cls.type_name())
            return value
        raise TypeValidationError(
            f"{cls.type_name()} expects {message_class.__name__}, got {type(value).__name__}"
        )

    @classmethod
    def convert(cls, output: Any, **kwargs: Any) -> Any:
        """What a component's ``output`` is published as (the upstream hook; default :meth:`validate`)."""
        return cls.validate(output)

    @classmethod
    def to_output(cls, value: Any) -> Any:
        """What a callback's ``get_output()`` returns for a received value (default: the value)."""
        return value

    @classmethod
    def example(cls) -> Any:
        """A small valid value, used for warm-ups and by the transport conformance tests."""
        raise NotImplementedError(f"{cls.type_name()} has no example value")


def convert_published(cls: type[SupportedType], value: Any, **kwargs: Any) -> Any:
    """What a publisher sends for ``value`` given publish keyword arguments (upstream's ``publish(output, **kwargs)``).

    The keyword arguments (``stream=``, ``done=``, ``frame_id=``, ``time_stamp=``, ...) reach the
    type's own ``convert(output, **kwargs)``; for a type without its own, ``frame_id`` and
    ``time_stamp`` (float seconds) set the header of a value that has one (a copy: the value
    given is not changed). Errors are :class:`TypeValidationError` naming the type.
    """
    if not kwargs:
        return cls.validate(value)
    message_class = cls.message_class()
    if _overrides_convert(cls):
        value = _converted(cls, value, message_class, kwargs)
    value = cls.validate(value)
    if not _overrides_convert(cls) and ("frame_id" in kwargs or "time_stamp" in kwargs):
        value = _with_header(cls, value, kwargs.get("frame_id"), kwargs.get("time_stamp"))
    return value


def _with_header(cls: type[SupportedType], value: Any, frame_id: Any, time_stamp: Any) -> Any:
    header = getattr(value, "header", None)
    if header is None or not hasattr(header, "frame_id"):
        return value
    import copy  # noqa: PLC0415  (rarely needed)

    if frame_id is not None and not isinstance(frame_id, str):
        raise TypeValidationError(f"{cls.type_name()}: frame_id must be a str, got {type(frame_id).__name__}")
    if time_stamp is not None and (isinstance(time_stamp, bool) or not isinstance(time_stamp, int | float)
                                   or not math.isfinite(time_stamp) or time_stamp < 0):
        raise TypeValidationError(f"{cls.type_name()}: time_stamp must be seconds >= 0, got {time_stamp!r}")
    new_header = copy.copy(header)
    if frame_id is not None:
        new_header.frame_id = frame_id
    if time_stamp is not None:
        new_header.stamp_ns = round(float(time_stamp) * 1e9)
    out = copy.copy(value)
    out.header = new_header
    return out


def check_convertible(cls: type[SupportedType]) -> None:
    """Refuse a type whose ``convert()`` output could not be checked: it defines ``convert`` but has
    neither a ``_ros_type`` nor a ``value_class`` (its values would be published unconverted).

    A type with neither and no ``convert`` of its own carries any JSON-like value as it is.
    """
    if cls.value_class is object and cls._ros_type is None and _overrides_convert(cls):
        raise ConfigError(
            f"message type {cls.type_name()!r} defines convert() but neither _ros_type nor value_class, so what "
            "it publishes cannot be checked or sent: set value_class to the class convert() returns, or "
            "_ros_type to the ROS message it builds")


def _overrides_convert(cls: type[SupportedType]) -> bool:
    return cls.convert.__func__ is not SupportedType.convert.__func__  # type: ignore[attr-defined]


def _converted(cls: type[SupportedType], value: Any, message_class: type[Any],
               kwargs: dict[str, Any] | None = None) -> Any:
    """``cls.convert(value, **kwargs)``, its failures as a TypeValidationError naming the type and, where known,
    the field."""
    name = cls.type_name()
    try:
        out = cls.convert(value, **(kwargs or {}))
    except TypeValidationError as exc:
        raise TypeValidationError(f"{name}: {exc}") from exc
    except KeyError as exc:
        raise TypeValidationError(f"{name}: field {exc.args[0]!r} is missing from the {type(value).__name__} "
                                  "to convert") from exc
    except Exception as exc:
        # rosidl's setters name the field ("The 'confidence' field must be of type 'float'").
        raise TypeValidationError(f"{name}: cannot convert {type(value).__name__} {_short(value)}: "
                                  f"{type(exc).__name__}: {exc}") from exc
    if not isinstance(out, message_class):
        raise TypeValidationError(f"{name}.convert returned {type(out).__name__}, not {message_class.__name__}")
    return out


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


_ROS_INT_BITS = {"int8": 8, "int16": 16, "int32": 32, "int64": 64, "char": 8}
_ROS_UINT_BITS = {"uint8": 8, "uint16": 16, "uint32": 32, "uint64": 64, "octet": 8, "byte": 8}
#: The largest finite float32, float(numpy.finfo(numpy.float32).max), written out: this module imports no numpy.
FLOAT32_MAX = 3.4028234663852886e38


def check_ros_message(message: Any, where: str) -> None:
    """Raise :class:`TypeValidationError` naming the first field of a ROS message whose value does not fit its type."""
    fields: dict[str, str] = type(message).get_fields_and_field_types()
    for name, kind in fields.items():
        _check_ros_field(getattr(message, name), kind, f"{where} field {name!r}")


def _check_ros_field(value: Any, kind: str, where: str) -> None:
    base, _, bound = kind.partition("[")
    if kind.startswith("sequence<"):
        base, bound = kind[len("sequence<"):].partition(">")[0].partition(",")[0], ""
    elif not bound:
        _check_ros_scalar(value, kind, where)
        return
    if isinstance(value, array.array | bytes) or is_ndarray(value):
        return  # typed storage: rosidl built it for the field's type
    if not isinstance(value, list | tuple):
        raise TypeValidationError(f"{where}: expected a sequence of {base}, got {type(value).__name__}")
    fixed = bound.rstrip("]")
    if fixed.isdigit() and len(value) != int(fixed):
        raise TypeValidationError(f"{where}: expected {fixed} values, got {len(value)}")
    for i, item in enumerate(value):
        _check_ros_scalar(item, base, f"{where}[{i}]")


def _check_ros_scalar(value: Any, kind: str, where: str) -> None:
    problem = ""
    if kind.startswith(("string", "wstring")):
        problem = "" if isinstance(value, str) else "str"
    elif kind == "boolean":
        problem = "" if isinstance(value, bool) or is_np_bool(value) else "bool"
    elif kind in ("float", "double"):
        if isinstance(value, bool) or not (isinstance(value, int | float) or is_np_number(value)):
            problem = "a number"
        elif kind == "float" and math.isfinite(float(value)) and abs(float(value)) > FLOAT32_MAX:
            problem = "a number within float32's range"
    elif kind in _ROS_INT_BITS or kind in _ROS_UINT_BITS:
        signed = kind in _ROS_INT_BITS
        bits = _ROS_INT_BITS[kind] if signed else _ROS_UINT_BITS[kind]
        low, high = (-(2 ** (bits - 1)), 2 ** (bits - 1)) if signed else (0, 2**bits)
        if isinstance(value, bytes) and len(value) == 1:
            return
        if isinstance(value, bool) or not (isinstance(value, int) or is_np_integer(value)) \
                or not low <= int(value) < high:
            problem = f"an int in [{low}, {high - 1}]"
    elif hasattr(value, "get_fields_and_field_types"):
        check_ros_message(value, where)
    if problem:
        raise TypeValidationError(f"{where}: expected {problem} ({kind}), got {type(value).__name__} {value!r:.40}")


def ros_message_class(msg_type: type[SupportedType]) -> type[Any]:
    """The ROS message class named by ``msg_type._ros_type`` (a class, ``"pkg/msg/Name"`` or ``"pkg.msg.Name"``).

    Raises :class:`ConfigError` saying which package to install when it cannot be imported.
    """
    ros_type = msg_type._ros_type
    if isinstance(ros_type, type):
        return ros_type
    if not isinstance(ros_type, str):
        raise ConfigError(f"{msg_type.type_name()}._ros_type must be a ROS message class or 'pkg/msg/Name', "
                          f"got {ros_type!r}")
    parts = ros_type.replace(".", "/").split("/")
    if len(parts) == 2:
        parts.insert(1, "msg")
    if len(parts) != 3 or not all(parts):
        raise ConfigError(f"{msg_type.type_name()}._ros_type {ros_type!r} is not of the form 'pkg/msg/Name'")
    package, kind, name = parts
    try:
        module = importlib.import_module(f"{package}.{kind}")
    except ImportError as exc:
        raise ConfigError(
            f"message type {msg_type.type_name()!r} travels as {package}/{kind}/{name}, but the ROS package "
            f"{package!r} is not installed in this environment ({exc}); build and install it (for a package of "
            "your own: pip install --no-build-isolation ./your_interfaces, see docs/ros2.md)"
        ) from exc
    found = getattr(module, name, None)
    if not isinstance(found, type):
        raise ConfigError(f"message type {msg_type.type_name()!r}: package {package!r} has no message {name!r}")
    return found


def shares_value_class(cls: type, base: type) -> bool:
    """The registries' subclass rule: ``cls`` may use ``base``'s entry (codec, conversion) when both are
    message types with the same value class, so that the entry's wire form fits ``cls``'s values."""
    return (isinstance(base, type) and issubclass(base, SupportedType) and base is not SupportedType
            and issubclass(cls, SupportedType) and base.value_class is cls.value_class)


_registry: Registry[type[SupportedType]] = Registry(
    "message type", hint="see agents_core.registered_types()", class_name=lambda cls: cls.__name__,
)


class _BuiltinTypes:
    """Registers the built-in types at the registry's first use (the family modules are imported then, not before)."""

    def __init__(self) -> None:
        self.register: Callable[[], None] | None = None
        self.ready = False
        self.loading = False
        self.lock = threading.RLock()

    def ensure(self) -> None:
        if self.ready:
            return
        with self.lock:
            # loading: add_additional_datatypes, called by the registration itself, on this thread.
            if self.ready or self.loading or self.register is None:
                return
            self.loading = True
            try:
                self.register()
                self.ready = True
            finally:
                self.loading = False


_builtin_types = _BuiltinTypes()


def install_builtin_types(register: Callable[[], None]) -> None:
    """Set what registers the built-in types (:mod:`agents_core.types` does, on import) before the registry's
    first use: their names then come before any user type's, in their own order."""
    _builtin_types.register = register


def add_additional_datatypes(types: Iterable[type[SupportedType]]) -> None:
    """Register message types so that ``Topic(msg_type="Name")`` resolves to them.

    Re-registering the same class is a no-op; registering a *different* class under a name
    that is taken raises :class:`ConfigError` (silently shadowing a type would change the
    wiring of every recipe that names it).
    """
    _builtin_types.ensure()
    for t in types:
        if not (isinstance(t, type) and issubclass(t, SupportedType)):
            raise ConfigError(f"{t!r} is not a SupportedType subclass")
        check_convertible(t)
        name = t.type_name()
        existing = _registry.find(name)
        if existing is not None and existing is not t:
            raise DuplicateNameError(f"message type name {name!r} is already registered by {existing.__module__}")
        _registry.register(name, t)


def get_type(name_or_type: str | type[SupportedType]) -> type[SupportedType]:
    """Resolve a registered type by name (or check a type token); unknown names list close matches."""
    if isinstance(name_or_type, type):
        if issubclass(name_or_type, SupportedType):
            check_convertible(name_or_type)
            name_or_type.message_class()
            return name_or_type
        raise UnknownTypeError(f"{name_or_type.__name__} is not a SupportedType")
    if not isinstance(name_or_type, str):
        raise UnknownTypeError(f"msg_type must be a SupportedType or its name, got {type(name_or_type).__name__}")
    _builtin_types.ensure()
    found = _registry.get(name_or_type)
    found.message_class()  # a _ros_type from a package that is not installed fails here, at topic creation
    return found


def registered_types() -> dict[str, type[SupportedType]]:
    """A snapshot of the registry: name -> type."""
    _builtin_types.ensure()
    return _registry.snapshot()
