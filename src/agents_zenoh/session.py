"""Opening the Zenoh session of a transport from its :class:`~agents_zenoh.config.ZenohConfig`.

See :mod:`agents_zenoh.config` for the loopback-safe defaults and the rendezvous they implement.
"""

from __future__ import annotations

import json
import logging

import zenoh

from agents_core.errors import ConfigError, TransportError

from .config import ZenohConfig
from .shm import shm_session_options

__all__ = ["effective_mode", "open_session", "zenoh_config"]

logger = logging.getLogger(__name__)

#: How a session retries an endpoint it lost (``connect/retry`` in Zenoh's config).
RECONNECT_RETRY = {"period_init_ms": 250, "period_max_ms": 1000, "period_increase_factor": 2}


def effective_mode(config: ZenohConfig) -> str:
    """The session mode after applying the config file (peer when neither says)."""
    if config.mode is not None:
        return config.mode
    if config.config_file is not None:
        mode = json.loads(_load_file(config).get_json("mode"))
        return str(mode or "peer")
    return "peer"


def _load_file(config: ZenohConfig) -> zenoh.Config:
    if config.config_file is None:
        return zenoh.Config()
    try:
        return zenoh.Config.from_file(config.config_file)
    except zenoh.ZError as exc:
        raise ConfigError(f"config_file {config.config_file!r}: {exc}") from exc


def zenoh_config(config: ZenohConfig, *, listen: list[str] | None = None,
                 connect: list[str] | None = None) -> zenoh.Config:
    """The ``zenoh.Config`` for ``config`` (``listen`` / ``connect`` override its fields)."""
    cfg = _load_file(config)
    if config.mode is not None:
        cfg.insert_json5("mode", json.dumps(config.mode))
    listen = listen if listen is not None else config.listen
    connect = connect if connect is not None else config.connect
    if listen is not None:
        cfg.insert_json5("listen/endpoints", json.dumps(listen))
    if connect is not None:
        cfg.insert_json5("connect/endpoints", json.dumps(connect))
    # Always set, even over a config file: Zenoh's own default is on, and it reaches the LAN.
    cfg.insert_json5("scouting/multicast/enabled", json.dumps(config.multicast_scouting))
    # A lost router (or peer) is retried every 0.25 s, doubling to at most 1 s (Zenoh's own default grows to 4 s):
    # a fleet is back within about a second of its router's restart. A config file or zenoh_options may say otherwise.
    if config.config_file is None or json.loads(cfg.get_json("connect/retry")) is None:
        cfg.insert_json5("connect/retry", json.dumps(RECONNECT_RETRY))
    # Needed by transient_local topics (Zenoh's advanced publisher caches timestamped samples).
    cfg.insert_json5("timestamping/enabled", "true")
    if not config.shared_memory:
        for key, value in shm_session_options(False).items():
            cfg.insert_json5(key, json.dumps(value))
    for key, value in config.zenoh_options.items():
        try:
            cfg.insert_json5(key, json.dumps(value))
        except zenoh.ZError as exc:
            raise ConfigError(f"zenoh_options[{key!r}] = {value!r}: {exc}") from exc
    return cfg


#: ids of the configs whose session joined a rendezvous someone else held (see :func:`joined_rendezvous`).
_JOINED: set[int] = set()


def joined_rendezvous(config: ZenohConfig) -> bool:
    """Whether the session just opened with ``config`` found the loopback rendezvous taken and joined its peers
    (asked once, right after :func:`open_session`: the answer is forgotten as it is given)."""
    if id(config) in _JOINED:
        _JOINED.discard(id(config))
        return True
    return False


def open_session(config: ZenohConfig) -> zenoh.Session:
    """Open the Zenoh session described by ``config``."""
    if config.multicast_scouting:
        logger.warning("Zenoh multicast scouting is ON: this process announces itself to, and links with, "
                       "Zenoh peers on every network it can reach")
    mode = effective_mode(config)
    rendezvous = f"tcp/127.0.0.1:{config.port}"
    from_file = config.config_file is not None
    listen, connect = config.listen, config.connect
    if not from_file and listen is None and connect is None:
        if mode == "peer":
            try:
                session = zenoh.open(zenoh_config(config, listen=[rendezvous], connect=[]))
            except zenoh.ZError:
                # Someone (another recipe, a router) already holds the rendezvous port: join it, and say so
                # (two unrelated recipes on one host would otherwise see each other's topics silently).
                logger.debug("Zenoh: %s is taken, joining the Zenoh peers there (another recipe or agentsctl on "
                            "this host: they share topics with this one; to keep recipes apart give each its own "
                            "AGENTS_ZENOH_PORT or AGENTS_ZENOH_NAMESPACE)", rendezvous)
                _JOINED.add(id(config))
                listen, connect = ["tcp/127.0.0.1:0"], [rendezvous]
            else:
                logger.info("Zenoh peer listening on %s (loopback rendezvous)", rendezvous)
                return session
        elif mode == "router":
            listen, connect = [rendezvous], []
        else:
            listen, connect = [], [rendezvous]
    elif not from_file:
        listen = listen if listen is not None else ([] if mode == "client" else ["tcp/127.0.0.1:0"])
        connect = connect if connect is not None else []
    try:
        session = zenoh.open(zenoh_config(config, listen=listen, connect=connect))
    except zenoh.ZError as exc:
        raise TransportError(f"cannot open a Zenoh {mode} session (listen={listen}, connect={connect}): {exc}") \
            from exc
    logger.info("Zenoh %s session open (listen=%s, connect=%s)", mode, listen, connect)
    return session
