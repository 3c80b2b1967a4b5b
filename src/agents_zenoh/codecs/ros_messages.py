"""Codecs of ROS message classes: a type declared the upstream way (``_ros_type``, no value class).

Such a message travels as a msgpack map of its fields: nested messages as maps, numeric sequences
and fixed-size arrays as numpy arrays (out of band, see :mod:`agents_zenoh.codecs.framing`), other
sequences as lists. The ROS message package is imported only when a codec for it is first built.
"""

from __future__ import annotations

import array
import functools
import importlib
import re
from typing import Any

import numpy as np

from .derivation import Codec
from .errors import CodecError

__all__ = ["ros_codec"]

# ROS primitive -> (numpy dtype, array.array typecode) for numeric sequences and arrays.
_ROS_NUMERIC: dict[str, tuple[str, str]] = {
    "float": ("<f4", "f"), "double": ("<f8", "d"), "int8": ("|i1", "b"), "uint8": ("|u1", "B"),
    "int16": ("<i2", "h"), "uint16": ("<u2", "H"), "int32": ("<i4", "i"), "uint32": ("<u4", "I"),
    "int64": ("<i8", "q"), "uint64": ("<u8", "Q"),
}
_ROS_SEQUENCE = re.compile(r"^sequence<([\w/]+)(?:, \d+)?>$|^([\w/]+)\[(\d*)\]$")


@functools.cache
def _ros_class(name: str) -> type:
    package, _, message = name.partition("/")
    module = importlib.import_module(f"{package}.msg")
    cls: type = getattr(module, message)
    return cls


def ros_codec(ros_class: type, type_name: str) -> Codec:
    """A ROS message as a msgpack map of its fields (cached per class)."""
    return _ros_codec_cached(ros_class, type_name)


@functools.cache
def _ros_codec_cached(ros_class: Any, type_name: str) -> Codec:
    """A ROS message as a msgpack map of its fields: nested messages as maps, numeric sequences as arrays."""
    fields: dict[str, str] = ros_class.get_fields_and_field_types()

    def encode_field(kind: str, value: Any) -> Any:
        seq = _ROS_SEQUENCE.match(kind)
        item = (seq.group(1) or seq.group(2)) if seq else None
        if item in _ROS_NUMERIC:
            return np.asarray(value, dtype=_ROS_NUMERIC[item][0])
        if item is not None:
            return [encode_field(item, v) for v in value]
        if "/" in kind:
            return ros_codec(_ros_class(kind), kind).encode(value)
        return value

    def decode_field(kind: str, doc: Any) -> Any:
        seq = _ROS_SEQUENCE.match(kind)
        item = (seq.group(1) or seq.group(2)) if seq else None
        if item in _ROS_NUMERIC:
            dtype, typecode = _ROS_NUMERIC[item]
            values = np.asarray(doc, dtype=dtype)
            if seq is not None and seq.group(3):  # a fixed-size array: rosidl keeps it as numpy
                return values.astype(values.dtype.newbyteorder("="))
            out = array.array(typecode)
            out.frombytes(np.ascontiguousarray(values, dtype=values.dtype.newbyteorder("=")).tobytes())
            return out
        if item is not None:
            if not isinstance(doc, list):
                raise CodecError(f"expected a list, got {type(doc).__name__}")
            return [decode_field(item, d) for d in doc]
        if "/" in kind:
            return ros_codec(_ros_class(kind), kind).decode(doc)
        return doc

    def encode(value: Any) -> Any:
        return {name: encode_field(kind, getattr(value, name)) for name, kind in fields.items()}

    def decode(doc: Any) -> Any:
        if not isinstance(doc, dict):
            raise CodecError(f"expected a map, got {type(doc).__name__}")
        message = ros_class()
        for name, kind in fields.items():
            if name in doc:
                try:
                    setattr(message, name, decode_field(kind, doc[name]))
                except Exception as exc:
                    raise CodecError(f"field {name!r}: {exc}") from exc
        return message

    schema = "{" + ", ".join(f'"{name}": {kind}' for name, kind in fields.items()) + "}"
    return Codec(type_name, encode, decode, f"{schema} (the fields of the ROS message)")
