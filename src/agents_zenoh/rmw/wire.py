"""rmw_zenoh's wire format: data keys, liveliness tokens, QoS strings, attachments and GIDs.

Pure functions (no ``zenoh`` import), implemented from rmw_zenoh's design document and sources:

- a topic's data key is ``<domain>/<name without leading/trailing '/'>/<pkg>::msg::dds_::<Type>_/<RIHS01 hash>``
  (a service's the same with ``srv``);
- an entity announces itself with a liveliness token
  ``@ros2_lv/<domain>/<zid>/<nid>/<id>/<NN|MP|MS|SS|SC>/<enclave>/<namespace>/<node>[/<name>/<type>/<hash>/<qos>]``
  where every '/' inside a part is written '%' (an empty namespace is ``%``);
- QoS is written ``rel:dur:hist,depth:dl_s,dl_ns:ls_s,ls_ns:live,lease_s,lease_ns``, each field empty where it
  equals rmw_zenoh's default (reliable, volatile, keep_last, depth 42, durations unset, automatic liveliness);
- every sample, query and reply carries an attachment of three fields in Zenoh's serialization: int64
  sequence number (from 1), int64 source timestamp (ns since the epoch), 16 bytes of GID (length-prefixed);
- an entity's GID is the XXH3-128 of its liveliness token, low 64 bits first, each half little-endian.
"""

from __future__ import annotations

import struct
from typing import NamedTuple

import xxhash
from attrs import define

__all__ = [
    "ADMIN_SPACE",
    "DEFAULT_QOS",
    "ENTITY_KINDS",
    "Attachment",
    "AttachmentError",
    "EntityToken",
    "Qos",
    "TokenError",
    "data_key",
    "dds_type_name",
    "decode_attachment",
    "demangle",
    "encode_attachment",
    "entity_token",
    "gid_of",
    "mangle",
    "parse_token",
    "qos_from_string",
    "qos_to_string",
]

ADMIN_SPACE = "@ros2_lv"
#: Node, publisher, subscription, service server, service client.
ENTITY_KINDS = ("NN", "MP", "MS", "SS", "SC")
_GID_SIZE = 16
_ATTACHMENT = struct.Struct("<qqB16s")


class TokenError(ValueError):
    """A liveliness token or key that is not in rmw_zenoh's format."""


class AttachmentError(ValueError):
    """An attachment that is not rmw_zenoh's (sequence number, timestamp, 16-byte GID)."""


def mangle(name: str) -> str:
    """A name as one key part: every '/' written as '%' (rmw_zenoh's mangle_name)."""
    return name.replace("/", "%")


def demangle(part: str) -> str:
    """The name a mangled key part stands for."""
    return part.replace("%", "/")


def dds_type_name(ros_type: str) -> str:
    """``pkg/msg/Type`` as rmw_zenoh writes it in keys: ``pkg::msg::dds_::Type_``."""
    parts = ros_type.split("/")
    if len(parts) != 3 or not all(parts):
        raise TokenError(f"ROS type {ros_type!r} is not package/kind/Type")
    pkg, kind, name = parts
    return f"{pkg}::{kind}::dds_::{name}_"


def data_key(domain_id: int, name: str, ros_type: str, type_hash: str) -> str:
    """The key expression a topic's samples (or a service's queries) travel on."""
    stripped = name.strip("/")
    if not stripped:
        raise TokenError(f"name {name!r} is empty")
    return f"{domain_id}/{stripped}/{dds_type_name(ros_type)}/{type_hash}"


@define(frozen=True)
class Qos:
    """The QoS fields rmw_zenoh writes in a token (ROS 2's enum numbers: reliable 1, best effort 2, ...)."""

    reliability: int = 1
    durability: int = 2
    history: int = 1
    depth: int = 42
    deadline: tuple[int, int] = (0, 0)
    lifespan: tuple[int, int] = (0, 0)
    liveliness: int = 1
    lease: tuple[int, int] = (0, 0)


#: rmw_zenoh's default QoS (fields equal to it are left empty in a token).
DEFAULT_QOS = Qos()
_VALID = {"reliability": (0, 1, 2, 3), "durability": (0, 1, 2, 3), "history": (0, 1, 2, 3),
          "liveliness": (0, 1, 2, 3, 4)}


def _field(value: int, default: int) -> str:
    return "" if value == default else str(value)


def qos_to_string(qos: Qos) -> str:
    """The QoS part of a token, as rmw_zenoh's qos_to_keyexpr writes it."""
    d = DEFAULT_QOS
    return ":".join([
        _field(qos.reliability, d.reliability),
        _field(qos.durability, d.durability),
        f"{_field(qos.history, d.history)},{_field(qos.depth, d.depth)}",
        ",".join(_field(v, dv) for v, dv in zip(qos.deadline, d.deadline, strict=True)),
        ",".join(_field(v, dv) for v, dv in zip(qos.lifespan, d.lifespan, strict=True)),
        ",".join([_field(qos.liveliness, d.liveliness),
                  *(_field(v, dv) for v, dv in zip(qos.lease, d.lease, strict=True))]),
    ])


def _number(text: str, default: int, what: str) -> int:
    if not text:
        return default
    if not text.isdigit() or len(text) > 20:
        raise TokenError(f"QoS {what} {text!r} is not a number")
    return int(text)


def qos_from_string(text: str) -> Qos:
    """Parse a token's QoS part (TokenError where it is not rmw_zenoh's format)."""
    parts = text.split(":")
    if len(parts) != 6:
        raise TokenError(f"QoS {text!r} has {len(parts)} parts, not 6")
    hist, dl, ls, live = (p.split(",") for p in parts[2:])
    if len(hist) != 2 or len(dl) != 2 or len(ls) != 2 or len(live) != 3:
        raise TokenError(f"QoS {text!r} is malformed")
    d = DEFAULT_QOS
    qos = Qos(
        reliability=_number(parts[0], d.reliability, "reliability"),
        durability=_number(parts[1], d.durability, "durability"),
        history=_number(hist[0], d.history, "history"), depth=_number(hist[1], d.depth, "depth"),
        deadline=(_number(dl[0], 0, "deadline"), _number(dl[1], 0, "deadline")),
        lifespan=(_number(ls[0], 0, "lifespan"), _number(ls[1], 0, "lifespan")),
        liveliness=_number(live[0], d.liveliness, "liveliness"),
        lease=(_number(live[1], 0, "lease"), _number(live[2], 0, "lease")))
    for name, allowed in _VALID.items():
        if getattr(qos, name) not in allowed:
            raise TokenError(f"QoS {text!r}: {name} {getattr(qos, name)} is not a ROS 2 value")
    return qos


class EntityToken(NamedTuple):
    """What a liveliness token says about one entity."""

    domain_id: int
    zid: str
    nid: str
    id: str
    kind: str
    enclave: str
    namespace: str
    node: str
    name: str = ""
    ros_type: str = ""
    type_hash: str = ""
    qos: Qos | None = None


def entity_token(domain_id: int, zid: str, nid: int | str, eid: int | str, kind: str, namespace: str, node: str,
                 *, enclave: str = "/", name: str = "", ros_type: str = "", type_hash: str = "",
                 qos: Qos | None = None) -> str:
    """The liveliness token of an entity (``kind`` one of NN, MP, MS, SS, SC).

    ``name`` is the entity's fully qualified topic or service name and ``ros_type`` its
    ``pkg::msg::dds_::Type_`` form (what rmw_zenoh writes); both are required except for a node.
    """
    if kind not in ENTITY_KINDS:
        raise TokenError(f"entity kind {kind!r} is not one of {', '.join(ENTITY_KINDS)}")
    parts = [ADMIN_SPACE, str(domain_id), zid, str(nid), str(eid), kind, mangle(enclave), mangle(namespace or "/"),
             mangle(node)]
    if kind != "NN":
        if not (name and ros_type and type_hash):
            raise TokenError(f"a {kind} token needs a name, a type and a type hash")
        parts += [mangle(name), mangle(ros_type), mangle(type_hash), qos_to_string(qos or DEFAULT_QOS)]
    if any(not p for p in parts):
        raise TokenError(f"token parts may not be empty: {parts}")
    return "/".join(parts)


_MAX_TOKEN = 4096


def parse_token(token: str) -> EntityToken:
    """What a liveliness token says (TokenError for anything that is not rmw_zenoh's format)."""
    if len(token) > _MAX_TOKEN:
        raise TokenError(f"liveliness token of {len(token)} characters is too long")
    parts = token.split("/")
    if len(parts) < 9 or parts[0] != ADMIN_SPACE:
        raise TokenError(f"not an rmw_zenoh liveliness token: {token[:120]!r}")
    if any(not p for p in parts):
        raise TokenError(f"liveliness token with an empty part: {token[:120]!r}")
    if not parts[1].isdigit() or len(parts[1]) > 9:
        raise TokenError(f"liveliness token with domain {parts[1][:20]!r}")
    kind = parts[5]
    if kind not in ENTITY_KINDS:
        raise TokenError(f"liveliness token with entity kind {kind[:20]!r}")
    base = EntityToken(int(parts[1]), parts[2], parts[3], parts[4], kind, demangle(parts[6]), demangle(parts[7]),
                       demangle(parts[8]))
    if kind == "NN":
        if len(parts) != 9:
            raise TokenError(f"node token with {len(parts)} parts: {token[:120]!r}")
        return base
    if len(parts) != 13:
        raise TokenError(f"{kind} token with {len(parts)} parts, not 13: {token[:120]!r}")
    return base._replace(name=demangle(parts[9]), ros_type=demangle(parts[10]), type_hash=demangle(parts[11]),
                         qos=qos_from_string(parts[12]))


def gid_of(token: str) -> bytes:
    """An entity's 16-byte GID: XXH3-128 of its liveliness token, low half first, little-endian halves."""
    digest = xxhash.xxh3_128_intdigest(token.encode())
    low, high = digest & (2**64 - 1), digest >> 64
    return low.to_bytes(8, "little") + high.to_bytes(8, "little")


class Attachment(NamedTuple):
    """rmw_zenoh's attachment: sequence number, source timestamp (ns), GID of the sender."""

    sequence_number: int
    source_timestamp: int
    gid: bytes


def encode_attachment(sequence_number: int, source_timestamp: int, gid: bytes) -> bytes:
    """The attachment bytes (Zenoh serialization of int64, int64 and a 16-byte sequence)."""
    if len(gid) != _GID_SIZE:
        raise AttachmentError(f"GID of {len(gid)} bytes, not {_GID_SIZE}")
    return _ATTACHMENT.pack(sequence_number, source_timestamp, _GID_SIZE, gid)


def decode_attachment(data: bytes | bytearray | memoryview | None) -> Attachment:
    """Read an attachment (AttachmentError for a missing or malformed one)."""
    if data is None:
        raise AttachmentError("the sample carries no attachment")
    if len(data) != _ATTACHMENT.size:
        raise AttachmentError(f"attachment of {len(data)} bytes, not {_ATTACHMENT.size}")
    seq, stamp, size, gid = _ATTACHMENT.unpack(bytes(data))
    if size != _GID_SIZE:
        raise AttachmentError(f"attachment GID length {size}, not {_GID_SIZE}")
    return Attachment(seq, stamp, gid)
