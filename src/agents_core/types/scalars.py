"""Numbers as builtins and numpy arrays: :class:`Bool`, ``Int32``/``Int64``, ``Float32``/``Float64`` and the
float ``MultiArray`` types. Their values are plain Python or numpy objects: no value class of their own."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, ClassVar

from ..errors import TypeValidationError
from ..support.lazy_numpy import is_ndarray, is_np_bool, is_np_integer, is_np_number, np, npt, numpy_attribute
from .base import FLOAT32_MAX, SupportedType
from .fields import as_numeric_array

__all__ = ["Bool", "Float32", "Float32MultiArray", "Float64", "Float64MultiArray", "Int32", "Int64"]


class Bool(SupportedType):
    """A boolean."""

    value_class = bool

    @classmethod
    def validate(cls, value: Any) -> Any:
        if isinstance(value, bool) or is_np_bool(value):
            return bool(value)
        raise TypeValidationError(f"Bool expects bool, got {type(value).__name__}")

    @classmethod
    def example(cls) -> Any:
        return True


def _integer(name: str, value: Any, bits: int) -> int:
    if isinstance(value, bool) or not (isinstance(value, int) or is_np_integer(value)):
        raise TypeValidationError(f"{name} expects int, got {type(value).__name__}")
    if not -(2 ** (bits - 1)) <= int(value) < 2 ** (bits - 1):
        raise TypeValidationError(f"{name} value {value} does not fit in {bits} bits")
    return int(value)


def _real(name: str, value: Any, single: bool) -> float:
    if isinstance(value, bool) or not (isinstance(value, int | float) or is_np_number(value)):
        raise TypeValidationError(f"{name} expects a number, got {type(value).__name__}")
    if single and math.isfinite(float(value)) and abs(float(value)) > FLOAT32_MAX:
        raise TypeValidationError(f"{name} value {value} overflows float32 (out of range: "
                                  f"|value| <= {FLOAT32_MAX:.8g})")
    return float(value)


class Int32(SupportedType):
    """A 32-bit signed integer, as ``int``."""

    value_class = int

    @classmethod
    def validate(cls, value: Any) -> Any:
        return _integer(cls.type_name(), value, 32)

    @classmethod
    def example(cls) -> Any:
        return -42


class Int64(Int32):
    """A 64-bit signed integer, as ``int``."""

    @classmethod
    def validate(cls, value: Any) -> Any:
        return _integer(cls.type_name(), value, 64)

    @classmethod
    def example(cls) -> Any:
        return 2**40


class Float32(SupportedType):
    """A single-precision float, as ``float``."""

    value_class = float

    @classmethod
    def validate(cls, value: Any) -> Any:
        return _real(cls.type_name(), value, single=True)

    @classmethod
    def example(cls) -> Any:
        return 0.5


class Float64(Float32):
    """A double-precision float, as ``float``."""

    @classmethod
    def validate(cls, value: Any) -> Any:
        return _real(cls.type_name(), value, single=False)

    @classmethod
    def example(cls) -> Any:
        return 3.141592653589793


class Float32MultiArray(SupportedType):
    """An n-dimensional float32 numpy array; array-likes (nested lists) are converted."""

    # numpy.ndarray and numpy.float32, looked up when first read: registering the type imports no numpy.
    value_class = numpy_attribute("ndarray")
    dtype: ClassVar[type[np.generic]] = numpy_attribute("float32")

    @classmethod
    def validate(cls, value: Any) -> Any:
        ndarray = is_ndarray(value)
        if ndarray and value.dtype == cls.dtype:
            return value
        if (ndarray or isinstance(value, Sequence)) and not isinstance(value, str | bytes):
            try:
                arr: npt.NDArray[Any] = as_numeric_array(value, None, "data")
                if arr.dtype.kind != "b":  # booleans are not numbers here, as before
                    return as_numeric_array(arr, cls.dtype, "data")
            except TypeValidationError as exc:
                raise TypeValidationError(f"{cls.type_name()} {exc}") from exc
        raise TypeValidationError(f"{cls.type_name()} expects a numeric array, got {type(value).__name__}")

    @classmethod
    def example(cls) -> Any:
        return np.arange(6, dtype=cls.dtype).reshape(2, 3)


class Float64MultiArray(Float32MultiArray):
    """An n-dimensional float64 numpy array."""

    dtype = numpy_attribute("float64")
