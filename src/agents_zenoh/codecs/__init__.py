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

from typing import TYPE_CHECKING

from agents_core.support.lazy import lazy_facade

from .derivation import Codec as Codec
from .derivation import schema_name as schema_name
from .errors import CodecError as CodecError
from .framing import MSGPACK as MSGPACK
from .framing import REUSE_ABOVE as REUSE_ABOVE
from .framing import pack as pack
from .framing import unpack as unpack
from .limits import DEFAULT_DECODE_LIMITS as DEFAULT_DECODE_LIMITS
from .limits import DecodeLimits as DecodeLimits
from .registry import MissingCodecError as MissingCodecError
from .registry import codec_for as codec_for
from .registry import decode_limits as decode_limits
from .registry import decode_value as decode_value
from .registry import decoder_for as decoder_for
from .registry import derive_codec as derive_codec
from .registry import encode_value as encode_value
from .registry import encoder_for as encoder_for
from .registry import plain_codec as plain_codec
from .registry import register_codec as register_codec
from .registry import set_decode_limits as set_decode_limits
from .schema_doc import builtin_schema_names as builtin_schema_names
from .schema_doc import describe_schemas as describe_schemas
from .schema_doc import schema_list as schema_list
from .schema_doc import update_schema_doc as update_schema_doc

if not TYPE_CHECKING:
    __getattr__, __dir__ = lazy_facade(__name__)
