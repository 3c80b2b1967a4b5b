"""``agentsctl foxglove``: serve a running recipe's topics (Zenoh or ROS 2) to Foxglove until Ctrl-C."""

from __future__ import annotations

import signal
import threading
import time
from typing import Annotated

import typer

from ..errors import ConfigError, UnknownTypeError
from ..foxglove.settings import FoxgloveSettings
from ..support.install_hint import install_hint
from ..topics import QoSConfig, Topic
from ..transport.contract import Transport
from ..types.base import get_type
from .connection import discovery_timeout, one_line_errors, open_transport
from .output import print_json, say
from .topics import ConnectOpt, DiscoveryOpt, JsonOpt, TransportOpt

__all__ = ["foxglove"]

#: Seconds between two discoveries of topics that appeared since the server started.
REDISCOVER_S = 2.0

# Best effort takes values from reliable and best-effort publishers alike (on ROS 2 a reliable
# subscriber cannot hear a best-effort publisher); depth 1 is the bridge's drop-to-latest anyway.
_VIEW_QOS = QoSConfig(reliability="best_effort", depth=1)


def _found_topics(transport: Transport, wanted: list[str] | None, timeout: float) -> tuple[list[Topic], list[str]]:
    """The discovered topics to serve (``wanted`` only, if given), and those skipped for their type."""
    topics, skipped = [], []
    for info in transport.discover(timeout=timeout).topics:
        if wanted is not None and info.name not in wanted:
            continue
        try:
            topics.append(Topic(info.name, get_type(info.msg_type), qos_profile=_VIEW_QOS))
        except UnknownTypeError:
            skipped.append(f"{info.name} ({info.msg_type})")
    return topics, skipped


@one_line_errors
def foxglove(transport: TransportOpt = None, connect: ConnectOpt = None,
             topic: Annotated[list[str] | None, typer.Option(
                 "--topic", help="serve only this topic (repeatable; default: every topic found)")] = None,
             host: Annotated[str, typer.Option("--host", help="bind address (127.0.0.1; another one needs "
                                                               "--insecure-remote)")] = "127.0.0.1",
             port: Annotated[int, typer.Option("--port", "-p", help="TCP port (0: any free one)",
                                               min=0, max=65535)] = 8765,
             insecure_remote: Annotated[bool, typer.Option(
                 "--insecure-remote", help="allow binding an address other machines reach: the Foxglove "
                                           "protocol has no token check, so anyone reaching it sees every topic")
             ] = False,
             seconds: Annotated[float, typer.Option("--seconds", help="stop after this long (0: until Ctrl-C)",
                                                    min=0.0)] = 0.0,
             json_out: JsonOpt = False, timeout: DiscoveryOpt = None) -> None:
    """Serve a running recipe's topics over the Foxglove WebSocket protocol (open ws://127.0.0.1:8765 in Foxglove).

    Images, detections (as image annotations), odometry and paths (3D), text and component status
    (as logs); other types as JSON. Topics that appear later are added every few seconds.
    """
    settings = FoxgloveSettings(host=host, port=port, insecure_remote=insecure_remote)
    try:
        from ..foxglove.bridge import FoxgloveBridge  # noqa: PLC0415 - needs the foxglove extra
    except ImportError as exc:
        raise ConfigError(f"agentsctl foxglove needs the 'foxglove' extra ({exc}); {install_hint('foxglove')}") \
            from None
    wanted = list(topic) if topic else None
    stop = threading.Event()
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, lambda *_: stop.set())
    with open_transport(transport, connect) as t:
        found, skipped = _found_topics(t, wanted, discovery_timeout(t, timeout))
        with FoxgloveBridge(t, found, settings) as bridge:
            served = bridge.topics()
            if json_out:
                print_json({"url": bridge.url, "topics": served, "skipped": skipped})
            else:
                say(f"Foxglove at {bridge.url} ({t.name}): {len(served)} topic(s)"
                    + (f"; not shown (no agents_core type): {', '.join(skipped)}" if skipped else ""))
            deadline = time.monotonic() + seconds if seconds > 0 else None
            while True:
                wait = REDISCOVER_S if deadline is None else min(REDISCOVER_S, deadline - time.monotonic())
                if wait <= 0 or stop.wait(wait):
                    break
                bridge.add_topics(_found_topics(t, wanted, discovery_timeout(t, timeout))[0])
