"""numpy, imported at its first use rather than with the message types.

Importing numpy costs more than the rest of a relay recipe's imports together (about 150 ms of a
cold start), and a recipe that only moves strings never needs it. The message-type modules
therefore use :data:`np`, a stand-in that imports numpy when one of its attributes is first read
(then keeps the attribute, so that later reads are plain attribute lookups), and the ``is_*``
checks below, which answer False without importing numpy when it is not loaded: a value cannot
be a numpy array or scalar if numpy was never imported.

:data:`npt` stands for ``numpy.typing`` the same way (``typing.get_type_hints`` on a value class, as the Zenoh
codecs do, evaluates annotations such as ``npt.NDArray[np.float32]``). For type checkers both *are* the modules.
"""

from __future__ import annotations

import importlib
import sys
from typing import TYPE_CHECKING, Any, TypeGuard

__all__ = ["is_ndarray", "is_np_bool", "is_np_integer", "is_np_number", "np", "npt", "numpy_attribute"]


class _LazyModule:
    """A module imported when an attribute is first read; each attribute is then kept on the stand-in."""

    def __init__(self, module: str) -> None:
        self._module = module

    def __getattr__(self, name: str) -> Any:
        # Only called for attributes not yet kept here.
        value = getattr(importlib.import_module(self._module), name)
        setattr(self, name, value)
        return value

    def __repr__(self) -> str:
        state = "loaded" if self._module in sys.modules else "not loaded"
        return f"<{self._module}, imported at first use ({state})>"


if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt
else:
    np = _LazyModule("numpy")
    #: numpy.typing: the value classes' string annotations name it, and typing.get_type_hints evaluates them.
    npt = _LazyModule("numpy.typing")


class _NumpyAttribute:
    """A class attribute whose value is ``numpy.<name>``, read when first looked up (a subclass may override it)."""

    def __init__(self, name: str) -> None:
        self._name = name
        self._value: Any = None

    def __get__(self, instance: Any, owner: type | None = None) -> Any:
        if self._value is None:  # kept: validation reads it for every value
            self._value = getattr(np, self._name)
        return self._value


def numpy_attribute(name: str) -> Any:
    """A class attribute standing for ``numpy.<name>`` (``value_class = numpy_attribute("ndarray")``),
    importing numpy only when the attribute is read."""
    return _NumpyAttribute(name)


#: (ndarray, bool_, integer, (integer, floating)) once numpy is loaded; None before.
_classes: tuple[Any, Any, Any, Any] | None = None


def _numpy_classes() -> tuple[Any, Any, Any, Any] | None:
    global _classes  # noqa: PLW0603 - filled once, when numpy is first seen loaded
    module = sys.modules.get("numpy")
    # A module that is still being imported (by another thread) is not complete yet: nothing can be its array.
    if module is None or not hasattr(module, "floating"):
        return None
    _classes = (module.ndarray, module.bool_, module.integer, (module.integer, module.floating))
    return _classes


def is_ndarray(value: Any) -> TypeGuard[npt.NDArray[Any]]:
    """``isinstance(value, numpy.ndarray)``, without importing numpy (False when it is not loaded)."""
    classes = _classes or _numpy_classes()
    return classes is not None and isinstance(value, classes[0])


def is_np_bool(value: Any) -> bool:
    """``isinstance(value, numpy.bool_)``, without importing numpy."""
    classes = _classes or _numpy_classes()
    return classes is not None and isinstance(value, classes[1])


def is_np_integer(value: Any) -> bool:
    """``isinstance(value, numpy.integer)``, without importing numpy."""
    classes = _classes or _numpy_classes()
    return classes is not None and isinstance(value, classes[2])


def is_np_number(value: Any) -> bool:
    """``isinstance(value, numpy.integer | numpy.floating)``, without importing numpy."""
    classes = _classes or _numpy_classes()
    return classes is not None and isinstance(value, classes[3])
