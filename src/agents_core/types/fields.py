"""The building blocks of the value classes: :class:`Header`, deep equality, field validators and converters.

Every structured value is a small attrs class (in the family modules of :mod:`agents_core.types`)
built from these: the :class:`Message` mixin (numpy-aware ``==``), the :func:`named` decorator
(construction errors name the class), a :func:`header_field`, and validators and array
converters that raise :class:`~agents_core.errors.TypeValidationError` naming the field that is
wrong. :class:`Wire` metadata says how a field is described in the Zenoh wire-format schema.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from typing import Any, TypeVar

import attrs
from attrs import define, field

from ..errors import TypeValidationError
from ..support.lazy_numpy import is_ndarray, is_np_bool, is_np_integer, is_np_number, np, npt

__all__ = [
    "FLOATS",
    "MAX_ARRAY_DIM",
    "Header",
    "Message",
    "Wire",
    "as_numeric_array",
    "check_holds",
    "empty_f64",
    "field_error",
    "header_field",
    "instance_of",
    "int_in",
    "is_bool",
    "is_number",
    "is_str",
    "is_str_list",
    "named",
    "now_ns",
    "to_array",
    "unstamped",
    "values_equal",
    "wire",
]

#: The largest dimension of any array field: ROS 2 sizes are uint32, and no array in one message is longer.
MAX_ARRAY_DIM = 2**32 - 1


def values_equal(a: Any, b: Any) -> bool:
    """Deep equality for message values (numpy arrays compared by dtype, shape and content)."""
    if is_ndarray(a) or is_ndarray(b):
        return (
            is_ndarray(a)
            and is_ndarray(b)
            and a.dtype == b.dtype
            and a.shape == b.shape
            and bool(np.array_equal(a, b, equal_nan=a.dtype.kind == "f"))
        )
    if attrs.has(type(a)):
        return type(a) is type(b) and all(
            values_equal(getattr(a, f.name), getattr(b, f.name)) for f in attrs.fields(type(a))
        )
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(values_equal(x, y) for x, y in zip(a, b, strict=True))
    return bool(a == b)


_M = TypeVar("_M")


def named(cls: type[_M]) -> type[_M]:
    """Prefix the construction errors of an attrs message class with its name ("ImuMsg field 'x': ...")."""
    init = cls.__init__

    @functools.wraps(init)
    def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
        try:
            init(self, *args, **kwargs)
        except TypeValidationError as exc:
            if str(exc).startswith(cls.__name__):
                raise
            raise TypeValidationError(f"{cls.__name__} {exc}") from exc

    cls.__init__ = __init__  # type: ignore[method-assign]
    return cls


class Message:
    """Mixin giving attrs message classes a numpy-aware ``==``."""

    def __eq__(self, other: object) -> bool:
        return values_equal(self, other)

    __hash__ = None  # type: ignore[assignment]  # mutable values: unhashable like lists


# -- field converters -------------------------------------------------------------------------


def check_holds(arr: npt.NDArray[Any], name: str) -> None:
    """Refuse an array whose shape claims more elements than its memory holds, or absurd dimensions.

    A broadcast or overlapping view (zero or too-small strides) of a few bytes can claim terabytes:
    any code that copies it (a transport, ``np.ascontiguousarray``) would then allocate them all.
    """
    if any(d > MAX_ARRAY_DIM for d in arr.shape):
        raise TypeValidationError(f"field {name!r}: shape {arr.shape} has a dimension above {MAX_ARRAY_DIM}")
    if arr.flags.c_contiguous or arr.flags.f_contiguous or arr.size == 0:
        return  # the common case, checked by numpy's flags: each element has memory of its own
    # Sorted by stride, each dimension must step over everything the smaller ones span.
    span = arr.itemsize
    for stride, size in sorted((abs(st), n) for st, n in zip(arr.strides, arr.shape, strict=True) if n > 1):
        if stride < span:
            raise TypeValidationError(
                f"field {name!r}: shape {arr.shape} claims more elements than its data holds (a broadcast "
                "or overlapping view); pass a copy, e.g. np.ascontiguousarray(...)"
            )
        span = stride * size


def as_numeric_array(value: Any, dtype: type[np.generic] | None, name: str) -> npt.NDArray[Any]:
    """``value`` (an array or an array-like such as nested lists) as a numpy array, of ``dtype`` if given.

    Refuses, with :class:`TypeValidationError` naming ``name``: ragged nesting, non-numeric items,
    and values that ``dtype`` cannot hold (an integer out of its range, a finite float beyond
    float32's), rather than letting numpy wrap them round or turn them into inf.
    """
    try:
        arr = value if is_ndarray(value) else np.asarray(value)
    except (TypeError, ValueError) as exc:  # ragged nesting: "inhomogeneous shape"
        raise TypeValidationError(f"field {name!r}: not a rectangular array ({exc})") from exc
    check_holds(arr, name)
    if arr.dtype.kind not in "biuf":
        raise TypeValidationError(f"field {name!r}: expected numbers, got an array of {arr.dtype} "
                                  f"(from {type(value).__name__})")
    if dtype is None or arr.dtype == dtype:
        return arr
    target = np.dtype(dtype)
    if arr.size and target.kind in "iu" and arr.dtype.kind in "iuf":
        if arr.dtype.kind == "f" and not bool(np.all(np.isfinite(arr) & (arr == np.trunc(arr)))):
            raise TypeValidationError(f"field {name!r}: expected whole numbers for {target}, got fractions or "
                                      "non-finite values")
        info = np.iinfo(target)
        low, high = arr.min(), arr.max()
        if low < info.min or high > info.max:
            raise TypeValidationError(f"field {name!r}: values from {low} to {high} do not fit {target} "
                                      f"({info.min}..{info.max})")
    elif arr.size and target == np.float32 and arr.dtype.kind == "f" and arr.dtype.itemsize > 4:
        finite = arr[np.isfinite(arr)]
        if finite.size and float(np.abs(finite).max()) > float(np.finfo(np.float32).max):
            raise TypeValidationError(f"field {name!r}: values beyond float32's range")
    return arr.astype(target)


def to_array(value: Any, dtype: type[np.generic], shape: tuple[int | None, ...], name: str) -> npt.NDArray[Any]:
    """``value`` as a numpy array of ``dtype`` whose shape matches ``shape`` (None = any size).

    Each array field calls it from a converter of its own, a named function: mypy's attrs plugin
    types ``__init__`` only from named converters.
    """
    arr = as_numeric_array(value, None, name)
    if arr.size == 0:
        try:
            arr = arr.reshape(tuple(0 if d is None else d for d in shape))
        except ValueError as exc:
            raise TypeValidationError(f"field {name!r}: cannot make a {dtype.__name__} array: {exc}") from exc
    arr = as_numeric_array(arr, dtype, name)
    if arr.ndim != len(shape) or any(d is not None and d != s for d, s in zip(shape, arr.shape, strict=True)):
        want = "x".join("N" if d is None else str(d) for d in shape)
        raise TypeValidationError(f"field {name!r}: expected shape {want}, got {arr.shape}")
    return arr


def empty_f64() -> npt.NDArray[np.float64]:
    """An empty float64 vector (the default of an optional per-joint or per-coefficient field)."""
    return np.zeros(0)


# -- field validators -------------------------------------------------------------------------


def field_error(attribute: attrs.Attribute[Any], expected: str, value: Any) -> TypeValidationError:
    """The error for a field whose value is not of the ``expected`` kind."""
    return TypeValidationError(f"field {attribute.name!r}: expected {expected}, got {type(value).__name__}")


def is_str(_: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    """Validator: a ``str``."""
    if not isinstance(value, str):
        raise field_error(attribute, "str", value)


def is_bool(_: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    """Validator: a ``bool`` (numpy's too)."""
    if not (isinstance(value, bool) or is_np_bool(value)):
        raise field_error(attribute, "bool", value)


def is_number(_: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    """Validator: an int or a float, Python's or numpy's (not a bool)."""
    if isinstance(value, bool) or not (isinstance(value, int | float) or is_np_number(value)):
        raise field_error(attribute, "a number", value)


def is_str_list(_: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    """Validator: a list (or tuple) of ``str``."""
    if not isinstance(value, list | tuple) or not all(isinstance(item, str) for item in value):
        raise field_error(attribute, "a list of str", value)


def instance_of(cls: type[Any], optional: bool = False) -> Callable[[Any, attrs.Attribute[Any], Any], None]:
    """Validator: an instance of ``cls`` (or None when ``optional``)."""

    def check(_: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
        if not (isinstance(value, cls) or (optional and value is None)):
            raise field_error(attribute, cls.__name__, value)

    return check


def int_in(low: int, high: int) -> Callable[[Any, attrs.Attribute[Any], Any], None]:
    """Validator: an int (not a bool) from ``low`` to ``high`` inclusive."""

    def check(_: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
        if isinstance(value, bool) or not (isinstance(value, int) or is_np_integer(value)) \
                or not low <= int(value) <= high:
            raise TypeValidationError(f"field {attribute.name!r}: expected an int from {low} to {high}, got {value!r}")

    return check


# -- wire-format metadata ---------------------------------------------------------------------


@define(frozen=True)
class Wire:
    """How a field is described in the Zenoh wire-format schema (``docs/zenoh-wire-format.md``).

    ``describe`` replaces the description derived from the field's type (``"float (s)"`` rather
    than ``"float"``); ``as_list`` sends a small numpy array as a plain msgpack list (friendlier to
    third-party clients than an array descriptor) instead of an out-of-band array.
    """

    describe: str | None = None
    as_list: bool = False
    #: A numpy structured array (named fields at byte offsets): sent as its field layout plus its raw bytes.
    structured: bool = False


def wire(describe: str | None = None, *, as_list: bool = False, structured: bool = False) -> dict[str, Any]:
    """Field metadata for :class:`Wire`: ``field(..., metadata=wire("[x, y, z] float", as_list=True))``."""
    return {"wire": Wire(describe, as_list, structured)}


#: Small vectors that travel as plain msgpack lists.
FLOATS = wire("[float, ...]", as_list=True)


# -- header -----------------------------------------------------------------------------------


def now_ns() -> int:
    """The current time in integer nanoseconds since the Unix epoch (a new header's stamp)."""
    return time.time_ns()


def header_field() -> Any:
    """The ``header`` field of a value class: a :class:`Header` stamped now by default."""
    return field(factory=Header, validator=instance_of(Header))


@named
@define(eq=False)
class Header(Message):
    """When and in which coordinate frame a value was produced.

    ``stamp_ns`` is integer nanoseconds since the Unix epoch (integer so that conversions to
    ROS ``sec``/``nanosec`` are exact); :attr:`stamp` gives it as float seconds.
    """

    stamp_ns: int = field(factory=now_ns, metadata=wire("int (ns since the Unix epoch)"))
    frame_id: str = field(default="", validator=is_str)

    @stamp_ns.validator
    def _check_stamp(self, _: attrs.Attribute[int], value: Any) -> None:
        if isinstance(value, bool) or not (isinstance(value, int) or is_np_integer(value)) or value < 0:
            raise TypeValidationError(f"field 'stamp_ns': expected a non-negative int, got {value!r}")

    @property
    def stamp(self) -> float:
        """The stamp in float seconds since the epoch."""
        return self.stamp_ns / 1e9


def unstamped() -> Header:
    """The header of a value whose standard wire form has none (e.g. geometry_msgs/Pose): stamp 0.

    Transports that cannot carry such a header deliver this one, so examples use it to round-trip.
    """
    return Header(stamp_ns=0)
