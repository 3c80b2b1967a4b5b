"""The codec registry: which codec each message type travels with, and the encode / decode entry points.

:func:`register_codec` adds a codec for a user-registered message type; a codec's ``encode``
returns a msgpack-able document (numpy arrays anywhere in it travel out of band, see
:mod:`agents_zenoh.codecs.framing`) and its ``decode`` turns such a document back into the value.
A registered type without one gets a codec derived from its value class (:func:`derive_codec`)
the first time it is asked for (:func:`codec_for`); a type with neither a value class nor a ROS
message (upstream allows such types) travels as plain msgpack, JSON-like values only
(:func:`plain_codec`). :func:`encode_value`, :func:`decode_value`
and :func:`decoder_for` frame and unframe a value under its type's codec and decode limits
(:func:`set_decode_limits` changes them).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import attrs

from agents_core import messages as m
from agents_core.support.registry import NotRegisteredError, Registry
from agents_core.supported_types import SupportedType, get_type, registered_types, shares_value_class
from agents_core.types import is_builtin_type

from .derivation import Codec, list_codec, struct_codec, value_class_codec
from .errors import CodecError
from .framing import NDARRAY_KEY, pack, unpack
from .limits import DEFAULT_DECODE_LIMITS, STRUCT_LIMITS, DecodeLimits, limits_for
from .ros_messages import ros_codec

__all__ = [
    "MissingCodecError",
    "codec_for",
    "decode_limits",
    "decode_value",
    "decoder_for",
    "derive_codec",
    "encode_value",
    "encoder_for",
    "plain_codec",
    "register_codec",
    "registered_codecs",
    "set_decode_limits",
]


class MissingCodecError(CodecError, NotRegisteredError):
    """A message type has no Zenoh codec (neither registered nor derivable)."""


_codecs: Registry[Codec] = Registry(
    "Zenoh codec", missing_error=MissingCodecError, missing_text="message type {name} has no {kind}",
    class_name=lambda cls: cls.type_name() if issubclass(cls, SupportedType) else cls.__name__,
    hint="register one with agents_zenoh.register_codec({name}, encode, decode), or register the type "
         "with add_additional_datatypes to derive it from its attrs value class",
)
_lock = threading.Lock()  # makes derive-then-register one step


def derive_codec(msg_type: type[SupportedType]) -> Codec | None:
    """The codec of ``msg_type`` derived from its value class, or None when it has no derivable one.

    An attrs value class travels as a map of its fields (nested attrs values and headers as
    maps, numpy arrays out of band, small vectors as lists where the field says so); a builtin
    value class (str, bool, int, float, bytes) or a numpy array with a ``dtype`` as itself; a
    ROS message class (a type declared with ``_ros_type``) as a map of the message's fields; a
    list type with an ``item`` type as a list of the item's documents.
    """
    codec = value_class_codec(msg_type)
    if codec is not None:
        return codec
    name = msg_type.type_name()
    if msg_type.value_class is object and getattr(msg_type, "_ros_type", None) is not None:
        return ros_codec(msg_type.message_class(), name)
    item = getattr(msg_type, "item", None)
    if msg_type.value_class is list and isinstance(item, type) and issubclass(item, SupportedType):
        return list_codec(name, codec_for(item))
    return None


#: What a value of a type without a value class may be made of on Zenoh: JSON's kinds (a tuple
#: travels as a list). Anything else has no defined wire form, so it is refused rather than guessed.
_PLAIN_SCALARS = (str, int, float, bool, type(None))


def _check_plain(type_name: str, value: Any, when: str) -> None:
    """Raise :class:`CodecError` unless ``value`` is JSON-like (walked iteratively: depth is the peer's choice)."""
    stack: list[tuple[Any, str]] = [(value, "value")]
    while stack:
        item, where = stack.pop()
        if isinstance(item, _PLAIN_SCALARS):
            continue
        if isinstance(item, dict):
            for key, sub in item.items():
                if not isinstance(key, str):
                    raise CodecError(f"{type_name} has no value_class, so it travels on Zenoh as plain msgpack with "
                                     f"str keys only; {when} {where} has the key {key!r}")
                if key == NDARRAY_KEY:
                    raise CodecError(f"{type_name}: {when} {where} uses the key {NDARRAY_KEY!r}, which the wire "
                                     "format reserves for numpy arrays")
                stack.append((sub, f"{where}[{key!r}]"))
        elif isinstance(item, list | tuple):
            stack.extend((sub, f"{where}[{i}]") for i, sub in enumerate(item))
        else:
            raise CodecError(f"{type_name} has no value_class, so it travels on Zenoh as plain msgpack: JSON-like "
                             f"values only (dict with str keys, list, tuple, str, int, float, bool, None); {when} "
                             f"{where} is a {type(item).__name__}. Give the type a value_class (an attrs class) "
                             "or register a codec with agents_zenoh.register_codec")


def plain_codec(msg_type: type[SupportedType]) -> Codec:
    """The codec of a type with neither a value class nor a ROS message: the value itself as msgpack.

    Only JSON-like values travel (dicts with str keys, lists, tuples as lists, str, int, float,
    bool, None); anything else is refused with a :class:`CodecError` naming the type, on publish
    and on receipt (a peer may send any document). Decoded under :data:`DEFAULT_DECODE_LIMITS`.
    """
    name = msg_type.type_name()

    def encode(value: Any) -> Any:
        _check_plain(name, value, "the published")
        return value

    def decode(document: Any) -> Any:
        _check_plain(name, document, "the received")
        return document

    return Codec(name, encode, decode, "JSON-like value (plain msgpack; the type has no value_class)",
                 DEFAULT_DECODE_LIMITS)


def _has_no_wire_form(msg_type: type[SupportedType]) -> bool:
    return (msg_type.value_class is object and getattr(msg_type, "_ros_type", None) is None
            and not is_builtin_type(msg_type))


def _register_derived(msg_type: type[SupportedType]) -> Codec | None:
    codec = derive_codec(msg_type)
    if codec is None and _has_no_wire_form(msg_type):
        codec = plain_codec(msg_type)
    if codec is None:
        return None
    codec = attrs.evolve(codec, limits=limits_for(msg_type))
    with _lock:
        existing = _codecs.find(msg_type.type_name())
        return existing if existing is not None else _codecs.register(msg_type.type_name(), codec)


def register_codec(type_name: str, encode: Callable[[Any], Any], decode: Callable[[Any], Any],
                   *, schema: str = "user-defined", limits: DecodeLimits | None = None) -> None:
    """Teach the Zenoh adapter a message type registered with ``add_additional_datatypes``.

    ``encode(value)`` returns a msgpack-able document (dicts, lists, str, int, float, bool,
    None, bytes, and numpy arrays, which travel without copies); ``decode(document)`` returns
    the value (it is then checked with the type's ``validate``). ``schema`` describes the
    document for :func:`describe_schemas`. ``limits`` bound what decoding a received sample may
    cost (default :data:`DEFAULT_DECODE_LIMITS`: documents up to 64 MiB, lists up to 262,144
    items; see :class:`DecodeLimits`). Registering again replaces the codec.
    """
    if not isinstance(type_name, str) or not type_name:
        raise CodecError(f"type_name must be a non-empty str, got {type_name!r}")
    if not callable(encode) or not callable(decode):
        raise CodecError(f"codec for {type_name!r}: encode and decode must be callables")
    if limits is not None and not isinstance(limits, DecodeLimits):
        raise CodecError(f"codec for {type_name!r}: limits must be a DecodeLimits, got {type(limits).__name__}")
    _codecs.register(type_name, Codec(type_name, encode, decode, schema, limits or DEFAULT_DECODE_LIMITS),
                     replace=True)


def _own_codec(msg_type: str | type[SupportedType]) -> Codec:
    if isinstance(msg_type, str):
        codec = _codecs.find(msg_type)
        # A name with a codec but no registered type (register_codec alone) is looked up directly.
        return codec if codec is not None else codec_for(get_type(msg_type))
    return codec_for(msg_type)


def decode_limits(msg_type: str | type[SupportedType]) -> DecodeLimits:
    """The limits that samples of ``msg_type`` (a type or its registered name) are decoded under."""
    return _own_codec(msg_type).limits


def set_decode_limits(msg_type: str | type[SupportedType], limits: DecodeLimits | None = None,
                      **changes: int) -> DecodeLimits:
    """Change what decoding a sample of ``msg_type`` may cost, process-wide; returns the new limits.

    Pass whole ``limits``, or the fields to change, e.g. for a detector that reports more than
    262,144 boxes per frame::

        set_decode_limits("Detections", max_array_len=1_000_000, max_containers=1_000_000)

    Applies to subscriptions created afterwards and to those already open (every sample looks its
    codec up). A type without a codec of its own (a subtype decoded by its base's codec) changes
    the base type's limits.
    """
    name = _own_codec(msg_type).type_name
    with _lock:
        codec = _codecs.get(name)
        try:
            new = attrs.evolve(limits if limits is not None else codec.limits, **changes)
        except TypeError as exc:
            raise CodecError(f"set_decode_limits({name!r}): {exc}") from exc
        _codecs.register(name, attrs.evolve(codec, limits=new), replace=True)
    return new


def codec_for(msg_type: type[SupportedType]) -> Codec:
    """The codec of ``msg_type``: its own, else its nearest base type's with the same value class
    (the registry's one subclass rule), else one derived from its value class if the type is registered.

    Raises :class:`CodecError` (with how to fix it) when there is none.
    """
    found = _codecs.find_for_class(msg_type, inherits=shares_value_class)
    if found is not None:
        return found
    name = msg_type.type_name()
    if registered_types().get(name) is msg_type:
        derived = _register_derived(msg_type)
        if derived is not None:
            return derived
    raise _codecs.missing(name)


def encode_value(msg_type: type[SupportedType], value: Any, into: bytearray | None = None) -> bytes | bytearray:
    """The payload for ``value`` (already validated as ``msg_type``); ``into`` as in :func:`pack`."""
    codec = codec_for(msg_type)
    try:
        return pack(codec.encode(value), into)
    except Exception as exc:
        raise CodecError(f"cannot encode the value as {msg_type.type_name()}: {exc}") from exc


def encoder_for(msg_type: type[SupportedType]) -> Callable[[Any, bytearray | None], bytes | bytearray]:
    """:func:`encode_value` for one type, with its codec looked up once (a publisher's hot path).

    The codec is the one registered when this is called.
    """
    encode, name = codec_for(msg_type).encode, msg_type.type_name()

    def encode_payload(value: Any, into: bytearray | None = None) -> bytes | bytearray:
        try:
            return pack(encode(value), into)
        except Exception as exc:
            raise CodecError(f"cannot encode the value as {name}: {exc}") from exc

    return encode_payload


def decoder_for(msg_type: type[SupportedType]) -> Callable[[bytes | bytearray | memoryview], Any]:
    """:func:`decode_value` for one type, with its codec and limits looked up once (a subscriber's hot path).

    The codec is the one registered when this is called.
    """
    codec = codec_for(msg_type)
    decode, limits, validate, name = codec.decode, codec.limits, msg_type.validate, msg_type.type_name()

    def decode_payload(payload: bytes | bytearray | memoryview) -> Any:
        try:
            return validate(decode(unpack(payload, limits)))
        except Exception as exc:
            raise CodecError(f"cannot decode the sample as {name}: {exc}") from exc

    return decode_payload


def decode_value(msg_type: type[SupportedType], payload: bytes | bytearray | memoryview) -> Any:
    """The value carried by ``payload``, validated as ``msg_type``; :class:`CodecError` if it does not decode."""
    codec = codec_for(msg_type)
    try:
        return msg_type.validate(codec.decode(unpack(payload, codec.limits)))
    except Exception as exc:
        raise CodecError(f"cannot decode the sample as {msg_type.type_name()}: {exc}") from exc


def registered_codecs() -> dict[str, Codec]:
    """Type name -> codec, for every codec registered or derived so far (a copy)."""
    return dict(_codecs.snapshot())


def _init_builtin() -> None:
    _codecs.register("Header", attrs.evolve(struct_codec(m.Header), limits=STRUCT_LIMITS))
    for msg_type in registered_types().values():
        if is_builtin_type(msg_type):
            _register_derived(msg_type)


_init_builtin()
