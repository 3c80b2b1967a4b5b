"""A client of the Foxglove WebSocket protocol, written from its published spec (foxglove/ws-protocol, docs/spec.md).

Independent of agents_core and of foxglove-sdk: ``websockets`` for the socket, the protocol's JSON
control messages (serverInfo, advertise, subscribe) and its binary message-data frame
(opcode 0x01, uint32 subscription id, uint64 timestamp in ns, little-endian, then the payload),
and ``google.protobuf`` to decode payloads with the FileDescriptorSet each channel advertises.

The subprotocol is offered under both names (``foxglove.websocket.v1``, and ``foxglove.sdk.v1``
which foxglove-sdk servers answer to: the same protocol renamed), as Foxglove's app does.
"""

from __future__ import annotations

import asyncio
import base64
import json
import struct
import time
from typing import Any

import websockets
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

SUBPROTOCOLS = ["foxglove.websocket.v1", "foxglove.sdk.v1"]
MESSAGE_DATA = 0x01


class FoxgloveClient:
    """One connection: the server's info, the channels it advertised, and received messages."""

    def __init__(self, ws: Any) -> None:
        self.ws = ws
        self.server_info: dict[str, Any] = {}
        self.channels: dict[str, dict[str, Any]] = {}  # by topic
        self.subscriptions: dict[int, dict[str, Any]] = {}  # subscription id -> channel
        self._next_sub = 100

    @classmethod
    async def connect(cls, url: str) -> FoxgloveClient:
        ws = await websockets.connect(url, subprotocols=SUBPROTOCOLS, max_size=64 * 1024 * 1024)
        client = cls(ws)
        client.server_info = json.loads(await asyncio.wait_for(ws.recv(), 5))
        assert client.server_info["op"] == "serverInfo", client.server_info
        return client

    async def close(self) -> None:
        await self.ws.close()

    async def wait_for_channels(self, topics: list[str], timeout: float = 10.0) -> None:
        """Read control messages until every topic in ``topics`` was advertised."""
        deadline = time.monotonic() + timeout
        while not all(t in self.channels for t in topics):
            left = deadline - time.monotonic()
            assert left > 0, f"not advertised within {timeout} s: {set(topics) - set(self.channels)}"
            self._control(await asyncio.wait_for(self.ws.recv(), left))

    def _control(self, raw: Any) -> None:
        if isinstance(raw, bytes):
            return
        doc = json.loads(raw)
        if doc["op"] == "advertise":
            for channel in doc["channels"]:
                self.channels[channel["topic"]] = channel
        elif doc["op"] == "unadvertise":
            for topic, channel in list(self.channels.items()):
                if channel["id"] in doc["channelIds"]:
                    del self.channels[topic]

    async def subscribe(self, topic: str) -> int:
        sub_id = self._next_sub
        self._next_sub += 1
        self.subscriptions[sub_id] = self.channels[topic]
        await self.ws.send(json.dumps({"op": "subscribe",
                                       "subscriptions": [{"id": sub_id, "channelId": self.channels[topic]["id"]}]}))
        return sub_id

    async def next_message(self, topic: str, timeout: float = 10.0) -> tuple[int, Any]:
        """The next message-data frame of ``topic``: (timestamp ns, decoded payload)."""
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            assert left > 0, f"no message on {topic} within {timeout} s"
            raw = await asyncio.wait_for(self.ws.recv(), left)
            if not isinstance(raw, bytes):
                self._control(raw)
                continue
            opcode, sub_id, stamp = struct.unpack_from("<BIQ", raw)
            assert opcode == MESSAGE_DATA, opcode
            channel = self.subscriptions[sub_id]
            if channel["topic"] == topic:
                return stamp, decode(channel, raw[13:])


def decode(channel: dict[str, Any], payload: bytes) -> Any:
    """A payload decoded by its channel's encoding: JSON as a dict, protobuf as a message object."""
    if channel["encoding"] == "json":
        return json.loads(payload)
    assert channel["encoding"] == "protobuf" and channel["schemaEncoding"] == "protobuf", channel
    files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(channel["schema"]))
    pool = descriptor_pool.DescriptorPool()
    for proto in files.file:
        pool.Add(proto)
    message_class = message_factory.GetMessageClass(pool.FindMessageTypeByName(channel["schemaName"]))
    return message_class.FromString(payload)
