"""How a recorded value becomes bytes in an MCAP file, and back: ROS 2 CDR where a type has a ROS form.

- ``cdr`` with a ``ros2msg`` schema (the ROS type name and its ``.msg`` definition): every type
  with a ROS 2 conversion (standard messages and ``agents_interfaces``), so ``ros2 bag``,
  ``rosbags`` and Foxglove read the file. Needs rclpy and the message packages (the ``ros2``
  extra); :mod:`agents_ros2.recording` does the work, loaded by name so the core never imports rclpy.
- ``agents-msgpack`` with a ``jsonschema`` schema: the framework's Zenoh wire form (a msgpack
  document followed by the raw array bytes, see ``docs/zenoh-wire-format.md``) for types with no
  ROS form, or everywhere when rclpy is absent; the schema describes the document.

Each channel also carries ``agents_type`` in its metadata (the agents_core type name), so a
player finds the value class without guessing; a file from ``ros2 bag`` (no such metadata) is
mapped back through the ROS type name.
"""

from __future__ import annotations

import importlib
import json
from collections.abc import Callable
from typing import Any, Literal

from attrs import define

from ..errors import ConfigError
from ..types.base import SupportedType

__all__ = ["CDR", "MSGPACK", "Encoding", "Preference", "decoder_for", "encoding_for", "type_for_schema"]

CDR = "cdr"
MSGPACK = "agents-msgpack"

#: Which form to write when a type has both: ``cdr`` (interoperable) or ``msgpack`` (no rclpy needed).
Preference = Literal["cdr", "msgpack"]


class _NoForm(Exception):
    """This encoding cannot carry that type (or its library is absent); the next one is tried."""


@define(frozen=True)
class Encoding:
    """How one message type is written: the MCAP message and schema encodings, the schema, and the codec."""

    message_encoding: str
    schema_name: str
    schema_encoding: str
    schema_data: bytes
    encode: Callable[[Any], bytes]
    decode: Callable[[bytes], Any]


def _cdr(msg_type: type[SupportedType]) -> Encoding:
    try:
        ros = importlib.import_module("agents_ros2.recording")
        name, definition, encode, decode = ros.cdr_codec(msg_type)
    except (ImportError, LookupError) as exc:  # no rclpy / message package, or no conversion
        raise _NoForm(str(exc)) from None
    return Encoding(CDR, name, "ros2msg", definition.encode(), encode, decode)


def _msgpack(msg_type: type[SupportedType]) -> Encoding:
    try:
        codecs = importlib.import_module("agents_zenoh.codecs")
        codec = codecs.codec_for(msg_type)
    except (ImportError, LookupError) as exc:
        raise _NoForm(str(exc)) from None
    name = msg_type.type_name()
    shape = codecs.describe_schemas().get(name, "")
    schema = {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": name, "type": "object",
              "description": "agents_core msgpack wire form (docs/zenoh-wire-format.md): one msgpack map "
                             f"followed by the raw bytes of its arrays. Fields: {shape}"}

    def encode(value: Any) -> bytes:
        return bytes(codecs.encode_value(msg_type, msg_type.validate(value)))

    del codec  # looked up only to fail here, at channel creation, for a type with no codec
    return Encoding(MSGPACK, f"agents_core/{name}", "jsonschema", json.dumps(schema).encode(), encode,
                    codecs.decoder_for(msg_type))


def encoding_for(msg_type: type[SupportedType], prefer: Preference = "cdr") -> Encoding:
    """The encoding to write ``msg_type`` with: ``prefer`` if it can carry the type, else the other.

    Raises :class:`~agents_core.errors.ConfigError` naming the extras when neither can.
    """
    order = (_cdr, _msgpack) if prefer == "cdr" else (_msgpack, _cdr)
    reasons = []
    for make in order:
        try:
            return make(msg_type)
        except _NoForm as exc:
            reasons.append(str(exc))
    raise ConfigError(f"cannot record {msg_type.type_name()}: no ROS 2 conversion and no msgpack codec "
                      f"({'; '.join(reasons)}); pip install 'agents-core[ros2]' or 'agents-core[zenoh]'")


def decoder_for(msg_type: type[SupportedType], message_encoding: str) -> Callable[[bytes], Any]:
    """Bytes written as ``message_encoding`` -> a value of ``msg_type``; ConfigError for an unknown encoding."""
    make = {CDR: _cdr, MSGPACK: _msgpack}.get(message_encoding)
    if make is None:
        raise ConfigError(f"message encoding {message_encoding!r} is not one agents_core reads ({CDR}, {MSGPACK})")
    try:
        return make(msg_type).decode
    except _NoForm as exc:
        raise ConfigError(f"cannot read {msg_type.type_name()} written as {message_encoding}: {exc}") from None


def type_for_schema(schema_name: str) -> type[SupportedType] | None:
    """The agents_core type of a channel without ``agents_type`` metadata, from its ROS schema name."""
    try:
        ros = importlib.import_module("agents_ros2.recording")
    except ImportError:
        return None
    found: type[SupportedType] | None = ros.type_for_ros_name(schema_name)
    return found
