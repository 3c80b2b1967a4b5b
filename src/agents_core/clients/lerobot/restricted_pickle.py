"""Unpickling network payloads without running the sender's code.

A pickle is a small program: every class or function it names is imported and called while it is
loaded, so ``pickle.loads`` on bytes from the network lets the sender run anything. Some protocols
(LeRobot's async inference) still send pickles. :func:`restricted_loads` reads them with an
allow-list: a payload may name only the globals given in ``allowed`` (module, name) -> the object
to use, and anything else fails with :class:`UnsafePayloadError` before it is imported. The map
also lets a payload's class path stand for a local class (``lerobot.async_inference.helpers.TimedAction``
-> our own dataclass of the same fields), so the sender's package need not be installed.

:data:`NUMPY_GLOBALS` admits plain numpy arrays and scalars (how numpy pickles them); object arrays
still go through the same allow-list for their elements.
"""

from __future__ import annotations

import io
import pickle
from collections.abc import Mapping
from typing import Any

import numpy as np

from ...errors import ProtocolError

__all__ = ["NUMPY_GLOBALS", "UnsafePayloadError", "restricted_loads"]


class UnsafePayloadError(ProtocolError):
    """A pickled payload names a global outside the allow-list, or is larger than allowed."""


def _numpy_globals() -> dict[tuple[str, str], Any]:
    # numpy pickles arrays as multiarray._reconstruct(ndarray, shape, dtype) + __setstate__, and
    # scalars as multiarray.scalar(dtype, bytes); numpy 2 moved the module to numpy._core and
    # still reads the old path, and a sender may run either version.
    try:
        from numpy._core import multiarray  # noqa: PLC0415  # numpy >= 2
    except ImportError:  # pragma: no cover - numpy 1.x
        from numpy.core import multiarray  # type: ignore[no-redef]  # noqa: PLC0415

    allowed: dict[tuple[str, str], Any] = {("numpy", "ndarray"): np.ndarray, ("numpy", "dtype"): np.dtype}
    for module in ("numpy.core.multiarray", "numpy._core.multiarray"):
        allowed[(module, "_reconstruct")] = multiarray._reconstruct
        allowed[(module, "scalar")] = multiarray.scalar
    # dtype classes (numpy >= 1.25 pickles a dtype by its class, e.g. numpy.dtypes.Float32DType)
    for dtype_name in ("Float16DType", "Float32DType", "Float64DType", "Int8DType", "Int16DType", "Int32DType",
                       "Int64DType", "UInt8DType", "UInt16DType", "UInt32DType", "UInt64DType", "BoolDType"):
        cls = getattr(getattr(np, "dtypes", None), dtype_name, None)
        if cls is not None:
            allowed[("numpy.dtypes", dtype_name)] = cls
    return allowed


#: The globals a pickle of plain numpy arrays (numeric and bool dtypes) and numpy scalars names.
NUMPY_GLOBALS: Mapping[tuple[str, str], Any] = _numpy_globals()


class _AllowListUnpickler(pickle.Unpickler):
    def __init__(self, data: bytes, allowed: Mapping[tuple[str, str], Any], what: str) -> None:
        super().__init__(io.BytesIO(data))
        self._allowed = allowed
        self._what = what

    def find_class(self, module: str, name: str) -> Any:
        try:
            return self._allowed[(module, name)]
        except KeyError:
            raise UnsafePayloadError(f"{self._what}: the payload names {module}.{name}, which is not on the "
                                     "allow-list; refused without importing it") from None

    def persistent_load(self, pid: Any) -> Any:
        raise UnsafePayloadError(f"{self._what}: the payload uses persistent ids, which are not allowed")


def restricted_loads(data: bytes, allowed: Mapping[tuple[str, str], Any], *, max_bytes: int,
                     what: str = "pickled payload") -> Any:
    """Unpickle ``data`` admitting only the globals in ``allowed``.

    :param allowed: (module, name) as the payload spells it -> the object to use for it.
    :param max_bytes: a longer payload is refused before reading it.
    :param what: names the payload in errors ("LeRobot actions from host:port").
    :raises UnsafePayloadError: a global outside ``allowed``, persistent ids, or too many bytes.
    :raises ProtocolError: the bytes are not a valid pickle.
    """
    if len(data) > max_bytes:
        raise UnsafePayloadError(f"{what}: {len(data)} bytes, more than the {max_bytes} allowed")
    try:
        return _AllowListUnpickler(data, allowed, what).load()
    except UnsafePayloadError:
        raise
    except (pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError, IndexError, KeyError,
            MemoryError) as exc:
        raise ProtocolError(f"{what}: not a readable pickle: {type(exc).__name__}: {exc}") from exc
