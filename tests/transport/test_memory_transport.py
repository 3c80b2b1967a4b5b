"""Memory-transport specifics beyond the conformance suite: zero-copy, statistics, latching, isolation."""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
import pytest

from agents_core.errors import TransportClosedError, WiringError
from agents_core.messages import ImageMsg
from agents_core.topics import QoSConfig, Topic
from agents_core.transport import MemoryTransport
from tests.conftest import wait_for


def test_delivery_is_zero_copy(memory: MemoryTransport) -> None:
    topic = Topic("camera", "Image")
    got: list[Any] = []
    memory.create_subscription(topic, got.append)
    msg = ImageMsg(data=np.zeros((480, 640, 3), np.uint8))
    memory.create_publisher(topic).publish(msg)
    assert wait_for(lambda: bool(got))
    assert got[0] is msg
    assert got[0].data is msg.data


def test_statistics_count_published_delivered_dropped(memory: MemoryTransport) -> None:
    topic = Topic("counts", "Int32", qos_profile=QoSConfig(depth=2))
    gate = threading.Event()
    seen: list[int] = []

    def blocked(v: int) -> None:
        seen.append(v)
        gate.wait(5.0)

    memory.create_subscription(topic, blocked)
    pub = memory.create_publisher(topic)
    pub.publish(0)
    assert wait_for(lambda: seen == [0])
    for i in range(1, 11):
        pub.publish(i)
    gate.set()
    assert memory.wait_for_idle()
    stats = memory.statistics()["counts"]
    assert stats.published == 11
    assert seen == [0, 9, 10]
    assert stats.delivered == 3
    assert stats.dropped == 8


def test_two_transports_are_independent() -> None:
    with MemoryTransport() as one, MemoryTransport() as two:
        topic = Topic("shared_name", "String")
        got: list[str] = []
        two.create_subscription(topic, got.append)
        one.create_publisher(topic).publish("only on one")
        assert one.wait_for_idle() and two.wait_for_idle()
        assert got == []
        assert "shared_name" not in two.statistics() or two.statistics()["shared_name"].published == 0


def test_transient_local_replays_to_late_subscribers(memory: MemoryTransport) -> None:
    topic = Topic("map", "String", qos_profile=QoSConfig(depth=2, durability="transient_local"))
    pub = memory.create_publisher(topic)
    for v in ["v1", "v2", "v3"]:
        pub.publish(v)
    got: list[str] = []
    memory.create_subscription(topic, got.append)
    assert wait_for(lambda: len(got) == 2)
    assert got == ["v2", "v3"]


def test_one_topic_name_carries_one_type(memory: MemoryTransport) -> None:
    memory.create_publisher(Topic("status", "String"))
    with pytest.raises(WiringError, match="already carries String"):
        memory.create_subscription(Topic("status", "Bool"), lambda v: None)


def test_closing_a_subscription_stops_delivery(memory: MemoryTransport) -> None:
    topic = Topic("t", "String")
    got: list[str] = []
    sub = memory.create_subscription(topic, got.append)
    pub = memory.create_publisher(topic)
    pub.publish("before")
    assert wait_for(lambda: got == ["before"])
    sub.close()
    sub.close()  # idempotent
    pub.publish("after")
    assert memory.wait_for_idle()
    assert got == ["before"]


def test_closed_transport_raises() -> None:
    transport = MemoryTransport()
    transport.close()
    transport.close()  # idempotent
    with pytest.raises(TransportClosedError):
        transport.create_publisher(Topic("x", "String"))
    with pytest.raises(TransportClosedError):
        transport.request("svc", {})
