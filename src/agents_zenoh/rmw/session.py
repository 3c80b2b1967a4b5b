"""The Zenoh session of the rmw_zenoh transport, configured as rmw_zenoh configures its own.

- ``ZENOH_SESSION_CONFIG_URI``: a Zenoh config file replacing the defaults;
- otherwise rmw_zenoh's defaults: a *peer* connecting to a router at ``tcp/localhost:7447``,
  listening on ``tcp/localhost:0``, multicast scouting off (gossip carries discovery);
- ``ZENOH_CONFIG_OVERRIDE``: ``key=value`` pairs separated by ``;`` (values in JSON5), applied last;
- ``ROS_DOMAIN_ID``: the domain (default 0).

Options given to the transport (``connect``, ``listen``, ``mode``, ``domain_id``) win over the
environment. After opening, the session must see a router within ``router_timeout`` seconds (rmw_zenoh
waits for one too): otherwise a :class:`~agents_core.errors.TransportError` says how to start one.
"""

from __future__ import annotations

import json
import os
import time
from typing import Any

import zenoh

from agents_core.errors import ConfigError, TransportError

__all__ = ["DEFAULT_ROUTER", "domain_from_environment", "open_rmw_session", "session_config"]

DEFAULT_ROUTER = "tcp/localhost:7447"


def domain_from_environment() -> int:
    """``ROS_DOMAIN_ID`` (0 when unset); ConfigError for a value that is not 0-232."""
    raw = os.environ.get("ROS_DOMAIN_ID", "").strip()
    if not raw:
        return 0
    if not raw.isdigit() or int(raw) > 232:
        raise ConfigError(f"ROS_DOMAIN_ID={raw!r} is not a domain id (0-232)")
    return int(raw)


def _overrides(text: str) -> list[tuple[str, str]]:
    pairs = []
    for item in text.split(";"):
        if not item.strip():
            continue
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"ZENOH_CONFIG_OVERRIDE item {item!r} is not key=value")
        pairs.append((key.strip(), value.strip()))
    return pairs


def session_config(*, mode: str | None = None, connect: list[str] | None = None, listen: list[str] | None = None,
                   zenoh_options: dict[str, Any] | None = None) -> zenoh.Config:
    """The ``zenoh.Config`` of an rmw_zenoh session (see the module docstring)."""
    uri = os.environ.get("ZENOH_SESSION_CONFIG_URI", "").strip()
    if uri:
        try:
            cfg = zenoh.Config.from_file(uri)
        except zenoh.ZError as exc:
            raise ConfigError(f"ZENOH_SESSION_CONFIG_URI={uri!r}: {exc}") from exc
    else:
        cfg = zenoh.Config()
        cfg.insert_json5("mode", json.dumps("peer"))
        cfg.insert_json5("connect/endpoints", json.dumps([DEFAULT_ROUTER]))
        cfg.insert_json5("listen/endpoints", json.dumps(["tcp/localhost:0"]))
        cfg.insert_json5("scouting/multicast/enabled", "false")
    # transient_local needs it (Zenoh's advanced publisher orders its cache by timestamp), as in rmw_zenoh's defaults.
    cfg.insert_json5("timestamping/enabled", "true")
    if mode is not None:
        cfg.insert_json5("mode", json.dumps(mode))
    if connect is not None:
        cfg.insert_json5("connect/endpoints", json.dumps(connect))
    if listen is not None:
        cfg.insert_json5("listen/endpoints", json.dumps(listen))
    for key, value in (zenoh_options or {}).items():
        cfg.insert_json5(key, json.dumps(value))
    for key, value in _overrides(os.environ.get("ZENOH_CONFIG_OVERRIDE", "")):
        try:
            cfg.insert_json5(key, value)
        except zenoh.ZError as exc:
            raise ConfigError(f"ZENOH_CONFIG_OVERRIDE {key}={value}: {exc}") from exc
    return cfg


def open_rmw_session(config: zenoh.Config, router_timeout: float) -> zenoh.Session:
    """Open the session and wait up to ``router_timeout`` s for a router (0: do not wait)."""
    try:
        session = zenoh.open(config)
    except zenoh.ZError as exc:
        raise TransportError(f"cannot open the rmw_zenoh session: {exc}") from exc
    if router_timeout <= 0:
        return session
    deadline = time.monotonic() + router_timeout
    while time.monotonic() < deadline:
        if list(session.info.routers_zid()):
            return session
        time.sleep(0.05)
    connect = json.loads(config.get_json("connect/endpoints") or "[]")
    session.close()  # type: ignore[no-untyped-call]
    raise TransportError(
        f"rmw_zenoh: no Zenoh router answered within {router_timeout:g} s at {', '.join(connect) or 'no endpoint'}. "
        "Start one on this machine (`agentsctl router --listen tcp/0.0.0.0:7447`, or `ros2 run rmw_zenoh_cpp "
        "rmw_zenohd`), or point the session at yours with "
        "ZENOH_CONFIG_OVERRIDE='connect/endpoints=[\"tcp/HOST:7447\"]' (transport option router_timeout=0 skips "
        "this check)")
