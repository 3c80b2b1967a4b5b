"""Settings of a Zenoh transport (pure data: this module does not import zenoh).

Defaults are loopback-safe: every endpoint is ``tcp/127.0.0.1`` and multicast scouting is off
unless asked for (Zenoh's own defaults listen on every interface and scout by multicast).

With no endpoints given, a peer uses a **loopback rendezvous** on :attr:`ZenohConfig.port`
(7447, Zenoh's usual port): the first process on the host listens there; later ones find it
taken, listen on an OS-chosen loopback port instead and connect to the first, and Zenoh's
gossip then links every peer to every other. So two recipes started with
``Launcher(transport="zenoh")`` reach each other with no configuration, and nothing leaves
the host. A client connects to ``tcp/127.0.0.1:<port>``; a router listens there.

Give ``listen`` / ``connect`` (or a Zenoh JSON5 ``config_file``) for anything else. The
session itself is opened by :func:`agents_zenoh.session.open_session`.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any, Literal

from attrs import define, field

from agents_core import base_validators
from agents_core.config import BaseAttrs
from agents_core.errors import ConfigError
from agents_core.topics import validate_topic_name

__all__ = ["PRIORITIES", "ZenohConfig"]

#: Names accepted in :attr:`ZenohConfig.priorities`, highest first (Zenoh's priority classes).
PRIORITIES = ("real_time", "interactive_high", "interactive_low", "data_high", "data", "data_low", "background")

_ENDPOINT_RE = re.compile(r"^[a-z][a-z0-9-]*/\S+$")


def _endpoints(_inst: Any, attribute: Any, value: Any) -> None:
    if value is None:
        return
    if isinstance(value, str) or not isinstance(value, list):
        raise ConfigError(f"{attribute.name} must be a list of endpoints such as 'tcp/127.0.0.1:7447'")
    for ep in value:
        if not isinstance(ep, str) or not _ENDPOINT_RE.match(ep):
            raise ConfigError(f"{attribute.name}: {ep!r} is not a Zenoh endpoint such as 'tcp/127.0.0.1:7447'")


def _namespace(value: Any) -> str:
    if not isinstance(value, str):
        raise ConfigError(f"namespace must be a str, got {type(value).__name__}")
    stripped = value.strip("/")
    if stripped:
        validate_topic_name(stripped, "namespace")
    return stripped


def _options(_inst: Any, _attribute: Any, value: Any) -> None:
    if not isinstance(value, dict) or not all(isinstance(k, str) for k in value):
        raise ConfigError("zenoh_options must map Zenoh config paths (str) to values")


def _bool(_inst: Any, attribute: Any, value: Any) -> None:
    if not isinstance(value, bool):
        raise ConfigError(f"{attribute.name} must be True or False, got {value!r}")


def _int(_inst: Any, attribute: Any, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(f"{attribute.name} must be an int, got {value!r}")


def _threshold(_inst: Any, attribute: Any, value: Any) -> None:
    if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
        raise ConfigError(f"{attribute.name} must be None or a positive int (bytes), got {value!r}")


def _priorities(_inst: Any, _attribute: Any, value: Any) -> None:
    if not isinstance(value, dict):
        raise ConfigError("priorities must map topic names to priority names")
    for topic, prio in value.items():
        if prio not in PRIORITIES:
            raise ConfigError(f"priorities[{topic!r}]: {prio!r} is not one of {list(PRIORITIES)}")


@define(kw_only=True)
class ZenohConfig(BaseAttrs):
    """How a :class:`~agents_zenoh.transport.ZenohTransport` opens its Zenoh session.

    :param mode: ``"peer"`` (default), ``"client"`` or ``"router"``; None keeps the
        ``config_file``'s mode (peer when there is no file).
    :param listen: endpoints to listen on. None: the loopback rendezvous when ``connect`` is
        None too (see the module doc), else ``tcp/127.0.0.1:0`` (an OS-chosen loopback port;
        none for a client), or the config file's endpoints when there is a file.
    :param connect: endpoints to connect to. None: the rendezvous when ``listen`` is None too,
        else none, or the config file's.
    :param namespace: prefix of every key expression (``<namespace>/<topic>``); default none.
    :param multicast_scouting: find peers by UDP multicast; off by default (it reaches the
        whole LAN), and a warning is logged when turned on. It overrides the config file.
    :param config_file: a Zenoh JSON5 config file to start from; the fields above that are
        set (not None) override it, and its endpoints are used as they are (Zenoh's defaults,
        all interfaces, where it sets none).
    :param port: the loopback port of the default endpoints.
    :param priorities: topic name -> Zenoh priority (one of :data:`PRIORITIES`) for topics
        that need other than ``"data"``.
    :param match_timeout: for this many seconds after a publisher is created, publishing
        waits until Zenoh has matched a subscriber (at most that long), so the first values
        are not lost to discovery; 0 disables.
    :param request_workers: threads serving incoming requests and lifecycle transitions.
    :param shared_memory: Zenoh's shared-memory transport between processes on this host (on by
        default, as in Zenoh: payloads above 3 KB then cross through shared memory, with a copy on
        each side); False turns it off, so every value takes the network path (loopback TCP).
    :param shm_threshold: None (default): no value is put from a pool of this transport's own.
        An int: values encoded to this many bytes or more are put from a shared-memory pool
        (:mod:`agents_zenoh.shm`), so Zenoh's own copy into shared memory is skipped; peers on
        other hosts still get the bytes over the network. Off by default because it measured no
        better than Zenoh's transport alone (``benchmarks/shm.py``). Needs ``shared_memory``.
    :param shm_pool_size: the size (bytes) of that pool, created on the first large value; when it
        is full a value takes the ordinary path.
    :param zenoh_options: raw Zenoh settings, key path -> value (e.g.
        ``{"scouting/delay": 50}``), applied last; for what has no field here.
    """

    mode: Literal["peer", "client", "router"] | None = field(
        default=None, validator=base_validators.in_([None, "peer", "client", "router"]))
    listen: list[str] | None = field(default=None, validator=_endpoints)
    connect: list[str] | None = field(default=None, validator=_endpoints)
    namespace: str = field(default="", converter=_namespace)
    multicast_scouting: bool = field(default=False, validator=_bool)
    config_file: str | None = field(default=None)
    port: int = field(default=7447, validator=[_int, base_validators.in_range(1, 65535)])
    priorities: dict[str, str] = field(factory=dict, validator=_priorities)
    match_timeout: float = field(default=0.5, validator=base_validators.in_range(0.0, 60.0))
    request_workers: int = field(default=4, validator=[_int, base_validators.in_range(1, 256)])
    shared_memory: bool = field(default=True, validator=_bool)
    shm_threshold: int | None = field(default=None, validator=_threshold)
    shm_pool_size: int = field(default=32 * 1024 * 1024, validator=[_int, base_validators.in_range(4096, 2**40)])
    zenoh_options: dict[str, Any] = field(factory=dict, validator=_options)

    @config_file.validator
    def _check_file(self, _attribute: Any, value: Any) -> None:
        if value is not None and not Path(value).is_file():
            raise ConfigError(f"config_file {value!r} does not exist")
