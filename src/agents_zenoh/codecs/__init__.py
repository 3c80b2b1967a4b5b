"""Msgpack codecs: the Zenoh wire form of every registered message type.

A sample's payload is one msgpack document (the type's schema, listed by
:func:`describe_schemas` and in ``docs/zenoh-wire-format.md``) followed by the raw bytes of its
numpy arrays. The package is split by concept; the names below are its public surface:

- :mod:`~agents_zenoh.codecs.framing`: :func:`pack` / :func:`unpack`, a document and its arrays
  as one payload (:data:`MSGPACK`, :data:`REUSE_ABOVE`).
- :mod:`~agents_zenoh.codecs.limits`: :class:`DecodeLimits`, what decoding a payload may cost,
  fitted per type family.
- :mod:`~agents_zenoh.codecs.derivation`: :class:`Codec`, and codecs derived from attrs value classes.
- :mod:`~agents_zenoh.codecs.ros_messages`: codecs of ROS message classes.
- :mod:`~agents_zenoh.codecs.registry`: which codec each type uses (:func:`register_codec`,
  :func:`codec_for`, :func:`encode_value`, :func:`decode_value`, :func:`set_decode_limits`, ...).
- :mod:`~agents_zenoh.codecs.schema_doc`: the schema list of the wire-format document
  (``python -m agents_zenoh.codecs docs/zenoh-wire-format.md`` rewrites it).

Each module imports only the ones listed before it (errors first), so there is no import circle.
"""

from __future__ import annotations

from .derivation import Codec, schema_name
from .errors import CodecError
from .framing import MSGPACK, REUSE_ABOVE, pack, unpack
from .limits import DEFAULT_DECODE_LIMITS, DecodeLimits
from .registry import (
    MissingCodecError,
    codec_for,
    decode_limits,
    decode_value,
    decoder_for,
    derive_codec,
    encode_value,
    encoder_for,
    plain_codec,
    register_codec,
    set_decode_limits,
)
from .schema_doc import builtin_schema_names, describe_schemas, schema_list, update_schema_doc

__all__ = [
    "DEFAULT_DECODE_LIMITS",
    "MSGPACK",
    "REUSE_ABOVE",
    "Codec",
    "CodecError",
    "DecodeLimits",
    "MissingCodecError",
    "builtin_schema_names",
    "codec_for",
    "decode_limits",
    "decode_value",
    "decoder_for",
    "derive_codec",
    "describe_schemas",
    "encode_value",
    "encoder_for",
    "pack",
    "plain_codec",
    "register_codec",
    "schema_list",
    "schema_name",
    "set_decode_limits",
    "unpack",
    "update_schema_doc",
]
