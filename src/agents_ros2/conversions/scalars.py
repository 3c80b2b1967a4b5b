"""ROS 2 conversions of the scalars and multi-arrays: ``std_msgs`` Bool, Int32/64, Float32/64 and
Float32/64MultiArray."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt
from std_msgs.msg import Bool as RosBool
from std_msgs.msg import Float32 as RosFloat32
from std_msgs.msg import Float32MultiArray as RosFloat32MultiArray
from std_msgs.msg import Float64 as RosFloat64
from std_msgs.msg import Float64MultiArray as RosFloat64MultiArray
from std_msgs.msg import Int32 as RosInt32
from std_msgs.msg import Int64 as RosInt64
from std_msgs.msg import MultiArrayDimension

from agents_core.errors import TypeValidationError

from .base import RosConversion, as_numpy, f32, seq

__all__ = ["CONVERSIONS", "scalar"]

# Numpy refuses more than 64 dimensions; the Zenoh codec accepts 32, and so does this side.
_MAX_NDIM = 32


def scalar(ros_type: type[Any], read: Callable[[Any], Any]) -> RosConversion:
    """The conversion of a ``std_msgs`` message with one ``data`` field, read back through ``read``."""
    return RosConversion(ros_type, lambda v: ros_type(data=v), lambda msg: read(msg.data))


def _multi_array(ros_type: type[Any], typecode: str, dtype: type[np.generic]) -> RosConversion:
    def to(v: npt.NDArray[Any]) -> Any:
        out = ros_type()
        stride = int(v.size)
        for i, size in enumerate(v.shape):
            out.layout.dim.append(MultiArrayDimension(label=f"dim{i}", size=int(size), stride=stride))
            stride = stride // size if size else 0
        out.data = seq(typecode, v.reshape(-1), dtype)
        return out

    def back(msg: Any) -> npt.NDArray[Any]:
        flat = as_numpy(msg.data, dtype)[msg.layout.data_offset:]
        if len(msg.layout.dim) > _MAX_NDIM:
            raise TypeValidationError(f"{ros_type.__name__}: layout has {len(msg.layout.dim)} dimensions; "
                                      f"at most {_MAX_NDIM} are accepted")
        shape = tuple(int(d.size) for d in msg.layout.dim) or (flat.size,)
        # Exact Python ints: dimensions that multiply past 2**64 never wrap round to the data's size.
        if math.prod(shape) != flat.size:
            raise TypeValidationError(
                f"{ros_type.__name__}: layout {shape} needs {math.prod(shape)} values, the message has {flat.size}"
            )
        if math.prod(d for d in shape if d) * flat.itemsize >= 2**63:
            # An empty array may not claim dimensions numpy cannot even describe (0 x 2**32 x 2**32).
            raise TypeValidationError(f"{ros_type.__name__}: layout {shape} claims absurd dimensions")
        return flat.reshape(shape)

    return RosConversion(ros_type, to, back)


#: The built-in conversions of this family.
CONVERSIONS: dict[str, RosConversion] = {
    "Bool": scalar(RosBool, bool),
    "Int32": scalar(RosInt32, int),
    "Int64": scalar(RosInt64, int),
    "Float32": RosConversion(RosFloat32, lambda v: RosFloat32(data=v), lambda msg: f32(msg.data)),
    "Float64": scalar(RosFloat64, float),
    "Float32MultiArray": _multi_array(RosFloat32MultiArray, "f", np.float32),
    "Float64MultiArray": _multi_array(RosFloat64MultiArray, "d", np.float64),
}
