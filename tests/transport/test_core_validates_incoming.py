"""The core validates incoming values once for every driver: the driver's own check, or the core's.

A driver that declares ``validates_incoming = True`` (Zenoh, ROS 2, memory) gets the delivery
itself as its sink; any other driver gets a sink that validates first, so that a value it decoded
but that does not fit the topic's type is rejected (counted as a decode error) and never reaches
a callback.
"""

from __future__ import annotations

from typing import Any

from agents_core.testing.helpers import wait_for
from agents_core.topics import Topic
from agents_core.transport.core import DriverTransport
from agents_core.transport.delivery import BoundedDelivery, ValidatingSink
from agents_core.transport.driver import Sink
from agents_core.transport.memory import MemoryDriver


class TrustingDriver(MemoryDriver):
    """A third party's driver that hands on whatever it decoded (it declares no validation of its own)."""

    name = "trusting"
    validates_incoming = False

    def __init__(self) -> None:
        super().__init__()
        self.sinks: list[Sink] = []

    def open_subscriber(self, topic: Topic, sink: Sink, owner: str | None) -> Any:
        self.sinks.append(sink)
        return super().open_subscriber(topic, sink, owner)


def test_the_core_validates_for_a_driver_that_does_not() -> None:
    driver = TrustingDriver()
    transport = DriverTransport(driver)
    got: list[Any] = []
    try:
        topic = Topic("words", "String")
        sub = transport.create_subscription(topic, got.append)
        (sink,) = driver.sinks
        assert isinstance(sink, ValidatingSink)
        sink.offer(12345)  # decoded, but not a String: refused
        sink.offer("hello")
        assert wait_for(lambda: got == ["hello"], timeout=5.0, interval=0.01)
        assert transport.statistics("words")["words"].decode_errors == 1
        assert sub.statistics().decode_errors == 1
    finally:
        transport.close()


def test_a_driver_that_validates_gets_the_delivery_itself() -> None:
    driver = TrustingDriver()
    type(driver).validates_incoming = True  # the class attribute the capabilities are read from
    try:
        transport = DriverTransport(driver)
        assert transport.capabilities.validates_incoming
        transport.create_subscription(Topic("w2", "String"), lambda _: None)
        assert isinstance(driver.sinks[0], BoundedDelivery)
        transport.close()
    finally:
        type(driver).validates_incoming = False
    assert MemoryDriver.capabilities.validates_incoming  # the built-in drivers declare it
