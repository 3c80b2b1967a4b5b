"""rmw_zenoh's wire format for the independent peers (``raw_ros_peer.py``, ``raw_action_peer.py``), written here.

None of agents_zenoh's code: only zenoh-python, rosbags and xxhash, and the installed type descriptions
(``share/<pkg>/<kind>/<Type>.json``). The peers run as scripts, so they import it as ``raw_wire``.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import xxhash
import zenoh
from rosbags.typesys import Stores, get_typestore
from zenoh import ext as zext

__all__ = ["SHARE", "attachment", "dds", "gid", "installed_hash", "open_session", "read_attachment", "store"]

#: The installed ROS packages' ``share`` folder.
SHARE = Path(os.environ.get("AMENT_PREFIX_PATH", sys.prefix).split(os.pathsep)[0]) / "share"
#: rosbags' ROS 2 Jazzy types (the peers register the rest).
store = get_typestore(Stores.ROS2_JAZZY)


def installed_hash(ros_type: str) -> str:
    """The RIHS01 type hash of ``pkg/kind/Type`` from its installed type description."""
    pkg, kind, name = ros_type.split("/")
    return str(json.loads((SHARE / pkg / kind / f"{name}.json").read_text())["type_hashes"][0]["hash_string"])


def dds(ros_type: str) -> str:
    """``pkg/kind/Type`` as rmw_zenoh writes it in keys and tokens."""
    pkg, kind, name = ros_type.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def gid(token: str) -> bytes:
    """An entity's GID: XXH3-128 of its token, each 64-bit half little-endian, the low one first."""
    d = xxhash.xxh3_128(token.encode()).digest()
    return d[8:][::-1] + d[:8][::-1]


def attachment(seq: int, g: bytes) -> bytes:
    """rmw_zenoh's attachment (sequence number, now in ns, GID) in Zenoh's own serialization."""
    return zext.z_serialize((zext.Int64(seq), zext.Int64(time.time_ns()), g)).to_bytes()


def read_attachment(raw: zenoh.ZBytes | None) -> tuple[int, int, bytes]:
    """Sequence number, timestamp and GID of an attachment."""
    assert raw is not None, "no attachment"
    seq, stamp, g = zext.z_deserialize(tuple[zext.Int64, zext.Int64, bytes], raw)
    return int(seq), int(stamp), bytes(g)


def open_session(router: str) -> zenoh.Session:
    """A peer connected to ``router``, listening on loopback only, multicast scouting off."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("connect/endpoints", json.dumps([router]))
    conf.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')
    conf.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(conf)
