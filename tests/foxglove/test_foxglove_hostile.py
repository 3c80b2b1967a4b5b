"""Hostile Foxglove clients do not take the server down, and binding off loopback needs an explicit opt-in."""

from __future__ import annotations

import asyncio
import json
import os

import pytest

pytest.importorskip("foxglove")
pytest.importorskip("google.protobuf")

import websockets

from agents_core import Launcher, Topic
from agents_core.errors import ConfigError
from agents_core.foxglove import FoxgloveBridge, FoxgloveSettings
from agents_core.transport.memory import MemoryTransport

from ..recipe_parts import Relay
from .ws_client import SUBPROTOCOLS, FoxgloveClient

pytestmark = pytest.mark.timeout(120)


async def _hostile(url: str) -> None:
    async with websockets.connect(url, subprotocols=SUBPROTOCOLS, max_size=None) as ws:
        await ws.recv()  # serverInfo
        for bad in ("{not json", json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": 999999}]}),
                    json.dumps({"op": "unsubscribe", "subscriptionIds": [424242]}), json.dumps({"op": "nope"}),
                    json.dumps([1, 2, 3]), b"\x02\x00\x00\x00garbage"):
            await ws.send(bad)
    with pytest.raises((websockets.ConnectionClosed, OSError)):
        async with websockets.connect(url, subprotocols=SUBPROTOCOLS, max_size=None) as ws:
            await ws.recv()
            await ws.send(b"\x01" + os.urandom(64 * 1024 * 1024))
            await asyncio.wait_for(ws.recv(), 10)
            await asyncio.wait_for(ws.recv(), 10)


async def _still_serves(bridge: FoxgloveBridge, transport: MemoryTransport) -> str:
    client = await FoxgloveClient.connect(bridge.url)
    try:
        await client.wait_for_channels(["/words"])
        await client.subscribe("/words")
        await asyncio.sleep(0.2)
        publisher = transport.create_publisher(Topic("words", "String"))
        publisher.publish("still here")
        _, log = await client.next_message("/words")
        return str(log.message)
    finally:
        await client.close()


def test_bad_json_unknown_subscriptions_and_huge_frames_do_not_stop_the_server() -> None:
    with MemoryTransport() as transport, \
            FoxgloveBridge(transport, [Topic("words", "String")], FoxgloveSettings(port=0)) as bridge:
        asyncio.run(_hostile(bridge.url))
        assert asyncio.run(_still_serves(bridge, transport)) == "still here"


@pytest.mark.parametrize("host", ["0.0.0.0", "::", "192.0.2.10"])
def test_binding_off_loopback_is_refused_without_the_opt_in(host: str) -> None:
    with pytest.raises(ConfigError, match="no token check"):
        FoxgloveSettings(host=host)
    launcher = Launcher("memory", quiet=True)
    launcher.add_pkg(components=[Relay(inputs=[Topic("a", "String")], outputs=[Topic("b", "String")],
                                       trigger=Topic("a", "String"), component_name="relay")])
    with pytest.raises(ConfigError, match="insecure_remote=True"):
        launcher.enable_foxglove(host=host)


def test_the_opt_in_is_explicit() -> None:
    # Only the settings are checked: tests bind 127.0.0.1 only, never an address other machines reach.
    assert FoxgloveSettings(host="0.0.0.0", insecure_remote=True).insecure_remote is True
    with pytest.raises(ConfigError):
        FoxgloveSettings(host="0.0.0.0", insecure_remote="yes")  # type: ignore[arg-type]


def test_settings_are_checked() -> None:
    for bad in ({"port": 70000}, {"port": True}, {"queue_depth": 0}, {"client_backlog": -1}):
        with pytest.raises(ConfigError):
            FoxgloveSettings(**bad)
    assert FoxgloveSettings().host == "127.0.0.1"
    assert FoxgloveSettings(host="localhost").port == 8765
