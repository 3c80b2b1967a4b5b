"""Codecs derived from value classes: an attrs message class travels as a msgpack map of its fields.

:class:`Codec` is how one message type travels (value -> document -> value, its schema in words,
its decode limits). :func:`struct_codec` derives one from an attrs class, field by field: each
field's wire form (a ``_Kind``) follows from its type hint and its ``Wire`` metadata
(:class:`agents_core.messages.Wire`): nested attrs values as maps, numpy arrays out of band (see
:mod:`agents_zenoh.codecs.framing`), small vectors as lists, unions of attrs classes tagged by a
``"type"`` key. :func:`value_class_codec` picks the derivation for a registered type's value
class; the registry (:mod:`agents_zenoh.codecs.registry`) adds ROS message classes and lists.
"""

from __future__ import annotations

import math
import re
import types
import typing
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import attrs
import numpy as np
import numpy.typing as npt
from attrs import define

from agents_core import messages as m
from agents_core.supported_types import registered_types

from .errors import CodecError
from .framing import NDARRAY_KEY
from .limits import DEFAULT_DECODE_LIMITS, MAX_DIM, DecodeLimits

if TYPE_CHECKING:
    from agents_core.supported_types import SupportedType

__all__ = ["Codec", "list_codec", "schema_name", "struct_codec", "value_class_codec"]


@define(frozen=True)
class Codec:
    """How one message type travels: value -> document -> value, the schema in words, its decode limits."""

    type_name: str
    encode: Callable[[Any], Any]
    decode: Callable[[Any], Any]
    schema: str = "user-defined"
    limits: DecodeLimits = DEFAULT_DECODE_LIMITS


class _Kind:
    """How one field of a structured type travels (see :func:`struct_codec`)."""

    def __init__(self, describe: str, encode: Callable[[Any], Any] = lambda v: v,
                 decode: Callable[[Any], Any] = lambda d: d) -> None:
        self.describe = describe
        self.encode = encode
        self.decode = decode


def _vector(describe: str) -> _Kind:
    # Small arrays travel as plain msgpack lists (friendlier to third-party clients than an
    # ndarray descriptor); the message class converts the list back to its numpy dtype.
    return _Kind(describe, encode=lambda arr: arr.tolist())


def _ndarray(describe: str) -> _Kind:
    def decode(doc: Any) -> Any:
        if not isinstance(doc, np.ndarray):
            raise CodecError(f"expected an ndarray map ({NDARRAY_KEY}, dtype, shape), got {type(doc).__name__}")
        return doc

    return _Kind(f"ndarray {describe}", decode=decode)


# A structured array's layout on the wire: at most this many fields, each at most this many bytes a record.
_MAX_RECORD_FIELDS, _MAX_RECORD_BYTES = 256, 65_536
_FIELD_DTYPE_RE = re.compile(r"^[<|][iuf][1248]$")


def _structured(describe: str | None) -> _Kind:
    """A numpy structured array (e.g. point cloud points): its field layout, its shape, and its raw bytes."""

    def encode(arr: npt.NDArray[Any]) -> Any:
        fields = [[name, offset, dtype.str] for name, (dtype, offset, *_) in arr.dtype.fields.items()]  # type: ignore[union-attr]
        raw = np.ascontiguousarray(arr).reshape(-1).view(np.uint8)
        return {"fields": fields, "itemsize": arr.dtype.itemsize, "shape": list(arr.shape), "data": raw}

    def decode(doc: Any) -> Any:
        if not isinstance(doc, dict) or not {"fields", "itemsize", "shape", "data"} <= doc.keys():
            raise CodecError("expected a map with fields, itemsize, shape and data")
        fields, itemsize, shape, raw = doc["fields"], doc["itemsize"], doc["shape"], doc["data"]
        if not isinstance(itemsize, int) or isinstance(itemsize, bool) or not 0 < itemsize <= _MAX_RECORD_BYTES:
            raise CodecError(f"itemsize {itemsize!r} is not an int from 1 to {_MAX_RECORD_BYTES}")
        if not isinstance(fields, list) or not 0 < len(fields) <= _MAX_RECORD_FIELDS:
            raise CodecError(f"fields must be a list of 1 to {_MAX_RECORD_FIELDS} [name, offset, dtype] entries")
        names, formats, offsets = [], [], []
        for entry in fields:
            if (not isinstance(entry, list) or len(entry) != 3 or not isinstance(entry[0], str)
                    or not isinstance(entry[1], int) or isinstance(entry[1], bool) or not isinstance(entry[2], str)
                    or not _FIELD_DTYPE_RE.match(entry[2])):
                raise CodecError(f"field entry {entry!r} is not [name, offset, dtype] with a numeric dtype "
                                 "such as '<f4'")
            name, offset, dtype = entry
            if not 0 <= offset <= itemsize - np.dtype(dtype).itemsize:
                raise CodecError(f"field {name!r} at offset {offset} does not fit a {itemsize}-byte record")
            names.append(name)
            formats.append(dtype)
            offsets.append(offset)
        if (not isinstance(shape, list) or len(shape) > 2
                or not all(isinstance(d, int) and not isinstance(d, bool) and 0 <= d <= MAX_DIM for d in shape)):
            raise CodecError(f"shape {shape!r} is not a list of at most 2 sizes")
        try:
            dtype_ = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": itemsize})
        except (TypeError, ValueError) as exc:
            raise CodecError(f"the fields do not make a record layout: {exc}") from exc
        if not isinstance(raw, np.ndarray) or raw.dtype != np.uint8 or raw.ndim != 1:
            raise CodecError("data must be a 1-D |u1 ndarray")
        if raw.size != math.prod(shape) * itemsize:
            raise CodecError(f"data has {raw.size} bytes; {shape} records of {itemsize} bytes need "
                             f"{math.prod(shape) * itemsize}")
        return raw.view(dtype_).reshape(tuple(shape))

    schema = ('{"fields": [[name, offset, dtype], ...], "itemsize": int, "shape": [int, ...], '
              '"data": ndarray |u1 (the records\' bytes)}')
    return _Kind(describe or schema, encode=encode, decode=decode)


def _nested(codec: Codec) -> _Kind:
    return _Kind(codec.type_name, encode=codec.encode, decode=codec.decode)


def _optional(kind: _Kind) -> _Kind:
    return _Kind(f"{kind.describe} | nil", encode=lambda v: None if v is None else kind.encode(v),
                 decode=lambda d: None if d is None else kind.decode(d))


def _list_of(kind: _Kind) -> _Kind:
    def decode(doc: Any) -> Any:
        if not isinstance(doc, list):
            raise CodecError(f"expected a list, got {type(doc).__name__}")
        out = []
        for i, item in enumerate(doc):
            try:
                out.append(kind.decode(item))
            except Exception as exc:
                raise CodecError(f"[{i}]: {exc}") from exc
        return out

    return _Kind(f"[{kind.describe}, ...]", encode=lambda v: [kind.encode(x) for x in v], decode=decode)


def _tagged(options: Mapping[str, Codec], classes: Mapping[type, str]) -> _Kind:
    """One of several structured types, told apart by an added ``"type"`` key."""

    def encode(value: Any) -> Any:
        name = classes[type(value)]
        return {"type": name, **options[name].encode(value)}

    def decode(doc: Any) -> Any:
        if not isinstance(doc, dict) or doc.get("type") not in options:
            raise CodecError(f"expected a map with 'type' one of {sorted(options)}")
        return options[doc["type"]].decode({k: v for k, v in doc.items() if k != "type"})

    names = " | ".join(f'{{"type": "{n}", ...{n}}}' for n in options)
    return _Kind(names, encode=encode, decode=decode)


# -- codecs derived from value classes ----------------------------------------------------------

#: What a plain (non-attrs) value class is called in the schemas.
_PLAIN_NAMES: dict[type, str] = {str: "str", bool: "bool", int: "int", float: "float", bytes: "bin"}


def schema_name(value_class: type) -> str:
    """The name a value class has in the schemas: its registered type's (``ImageMsg`` -> ``Image``)."""
    for name, t in registered_types().items():
        if t.value_class is value_class:
            return name
    return value_class.__name__.removesuffix("Msg")


def _field_hints(cls: type) -> dict[str, Any]:
    try:
        return typing.get_type_hints(cls)
    except Exception:
        # A class defined in a function may name locals in string annotations: use the annotations that
        # are already objects; the others travel as they are (the class's converters see them on decode).
        return {f.name: f.type for f in attrs.fields(cls) if f.type is not None and not isinstance(f.type, str)}


def _is_union(hint: Any) -> bool:
    return typing.get_origin(hint) in (typing.Union, types.UnionType)


def _kind_for(hint: Any, spec: m.Wire, seen: dict[type, Codec]) -> _Kind:
    """The wire form of a field with type ``hint`` (see :class:`agents_core.messages.Wire` for ``spec``)."""
    origin = typing.get_origin(hint)
    if hint is np.ndarray or origin is np.ndarray:
        if spec.structured:
            return _structured(spec.describe)
        if spec.as_list:
            return _vector(spec.describe or "[float, ...]")
        return _ndarray(spec.describe or "any shape")
    if _is_union(hint):
        options = [a for a in typing.get_args(hint) if a is not type(None)]
        optional = len(options) < len(typing.get_args(hint))
        if len(options) == 1:
            kind = _kind_for(options[0], m.Wire(), seen)
        elif all(attrs.has(a) for a in options):
            codecs = {schema_name(a): struct_codec(a, seen) for a in options}
            kind = _tagged(codecs, {a: schema_name(a) for a in options})
        else:
            kind = _Kind(" | ".join(_describe_plain(a) for a in options))
        kind = _optional(kind) if optional else kind
        if spec.describe:
            kind.describe = spec.describe
        return kind
    if isinstance(hint, type) and attrs.has(hint):
        return _nested(struct_codec(hint, seen))
    if origin is list:
        (item,) = typing.get_args(hint) or (Any,)
        if (isinstance(item, type) and attrs.has(item)) or _is_union(item):
            kind = _list_of(_kind_for(item, m.Wire(), seen))
            if spec.describe:
                kind.describe = spec.describe
            return kind
    return _Kind(spec.describe or _describe_plain(hint))


def _describe_plain(hint: Any) -> str:
    if typing.get_origin(hint) is list:
        (item,) = typing.get_args(hint) or (Any,)
        return f"[{_describe_plain(item)}, ...]"
    if isinstance(hint, type):
        return _PLAIN_NAMES.get(hint, hint.__name__)
    return "any"


def struct_codec(cls: type, seen: dict[type, Codec] | None = None) -> Codec:
    """The codec of an attrs message class: a msgpack map with one key per field, in field order."""
    seen = {} if seen is None else seen
    if cls in seen:
        return seen[cls]
    hints = _field_hints(cls)
    fields: dict[str, _Kind] = {}
    for f in attrs.fields(cls):
        if not f.init:
            continue  # derived state, rebuilt by the class
        spec = f.metadata.get("wire", m.Wire())
        fields[f.name] = _kind_for(hints.get(f.name, Any), spec, seen)

    # Fields added after the wire format was fixed (a Detections' depth) are left out while None,
    # so the payloads of values without them stay byte for byte what they were.
    omitted = {f.name for f in attrs.fields(cls) if f.metadata.get("omit_when_none")}

    def encode(value: Any) -> Any:
        return {name: kind.encode(item) for name, kind in fields.items()
                if (item := getattr(value, name)) is not None or name not in omitted}

    def decode(doc: Any) -> Any:
        if not isinstance(doc, dict):
            raise CodecError(f"expected a map, got {type(doc).__name__}")
        kwargs = {}
        # Unknown keys are ignored (a newer publisher may add fields); a missing key takes the
        # field's default, so a third-party client may leave out e.g. the header.
        for name, kind in fields.items():
            if name in doc:
                try:
                    kwargs[name] = kind.decode(doc[name])
                except Exception as exc:
                    raise CodecError(f"field {name!r}: {exc}") from exc
        try:
            return cls(**kwargs)
        except TypeError as exc:
            raise CodecError(str(exc)) from exc

    schema = "{" + ", ".join(f'"{name}": {kind.describe}' for name, kind in fields.items()) + "}"
    codec = Codec(schema_name(cls), encode, decode, schema)
    seen[cls] = codec
    return codec


def _plain(type_name: str, describe: str) -> Codec:
    # The document is the value itself; decode_value checks it with the type's validate().
    return Codec(type_name, lambda v: v, lambda d: d, describe)



def value_class_codec(msg_type: type[SupportedType]) -> Codec | None:
    """The codec of ``msg_type`` derived from its value class alone, or None when that is not derivable.

    An attrs value class travels as a map of its fields (:func:`struct_codec`); a builtin value
    class (str, bool, int, float, bytes) or a numpy array with a ``dtype`` as itself.
    """
    name = msg_type.type_name()
    value_class = msg_type.value_class
    if attrs.has(value_class):
        return attrs.evolve(struct_codec(value_class), type_name=name)
    if value_class in _PLAIN_NAMES:
        return _plain(name, _PLAIN_NAMES[value_class])
    dtype = getattr(msg_type, "dtype", None)
    if value_class is np.ndarray and dtype is not None:
        return _plain(name, f"ndarray {np.dtype(dtype).str}, any shape")
    return None


def list_codec(type_name: str, item: Codec) -> Codec:
    """The codec of a list type: a msgpack list of ``item``'s documents."""
    kind = _list_of(_nested(item))
    return Codec(type_name, kind.encode, kind.decode, kind.describe)
