"""The test's own transports: Zenoh's driver under the name ``zenloop``, the memory driver under ``memloop``."""

from __future__ import annotations

from typing import Any

from agents_core.transport.core import DriverTransport
from agents_core.transport.memory import MemoryDriver
from agents_zenoh.config import ZenohConfig
from agents_zenoh.transport import ZenohDriver, options_from_environment

__all__ = ["MemloopTransport", "ZenloopTransport"]


class ZenloopDriver(ZenohDriver):
    """Zenoh's primitives, resolved by another name."""

    name = "zenloop"


class ZenloopTransport(DriverTransport):
    """A cross-process transport no module of agents_core knows (options: :class:`ZenohConfig` fields)."""

    driver: ZenloopDriver

    def __init__(self, **options: Any) -> None:
        config = ZenohConfig.from_dict({**options_from_environment(), **options}, source="zenloop options")
        super().__init__(ZenloopDriver(config), request_workers=config.request_workers)


class MemloopDriver(MemoryDriver):
    """The memory driver, resolved by another name."""

    name = "memloop"


class MemloopTransport(DriverTransport):
    """An in-process transport of the test's own."""

    def __init__(self, **options: Any) -> None:
        super().__init__(MemloopDriver(), **options)
