"""A page never shows a state its component has left: status frames are latest-wins for each client."""

from __future__ import annotations

import asyncio
import json
import time

import pytest

pytest.importorskip("starlette", reason="the ui extra is not installed (pip install 'agents-core[ui]')")

from agents_core.messages import ComponentStatusMsg, Header
from agents_core.testing.helpers import wait_for
from agents_core.transport import MemoryTransport
from agents_core.transport.core import status_topic
from agents_core.ui.hub import OutputHub


def _drain(queue: asyncio.Queue) -> list[str]:
    frames = []
    while not queue.empty():
        frames.append(json.loads(queue.get_nowait())["state"])
    return frames


def test_a_burst_of_statuses_reaches_a_new_client_as_the_newest_only() -> None:
    transport = MemoryTransport()
    loop = asyncio.new_event_loop()
    hub = OutputHub(transport, [], ["arm"])
    publisher = transport.create_publisher(status_topic("arm"))
    try:
        hub.start(loop)
        for state in ("configuring", "inactive", "activating", "active"):
            publisher.publish(ComponentStatusMsg(component="arm", lifecycle_state=state))
        assert wait_for(lambda: (hub.latest_status("arm") or {}).get("state") == "active", 5.0)
        # The four fan-outs are still waiting on the loop when this client connects.
        client = hub.connect()
        loop.run_until_complete(asyncio.sleep(0.05))
        assert _drain(client.queue) == ["active"]
        publisher.publish(ComponentStatusMsg(component="arm", lifecycle_state="deactivating"))
        assert wait_for(lambda: (hub.latest_status("arm") or {}).get("state") == "deactivating", 5.0)
        loop.run_until_complete(asyncio.sleep(0.05))
        assert _drain(client.queue) == ["deactivating"]
    finally:
        hub.stop()
        publisher.close()
        transport.close()
        loop.close()


def test_a_sender_whose_clock_stepped_back_is_still_shown() -> None:
    """Only a status stamped shortly before the one shown is taken for a late backlog value."""
    transport = MemoryTransport()
    loop = asyncio.new_event_loop()
    hub = OutputHub(transport, [], ["arm"])
    publisher = transport.create_publisher(status_topic("arm"))
    now = time.time_ns()
    try:
        hub.start(loop)
        publisher.publish(ComponentStatusMsg(component="arm", lifecycle_state="active", header=Header(stamp_ns=now)))
        assert wait_for(lambda: (hub.latest_status("arm") or {}).get("state") == "active", 5.0)
        late = ComponentStatusMsg(component="arm", lifecycle_state="inactive", header=Header(stamp_ns=now - 10**9))
        publisher.publish(late)  # 1 s older: a late backlog value, not news
        stepped = ComponentStatusMsg(component="arm", lifecycle_state="deactivating",
                                     header=Header(stamp_ns=now - 3600 * 10**9))
        publisher.publish(stepped)  # an hour older: the sender's clock stepped back
        assert wait_for(lambda: (hub.latest_status("arm") or {}).get("state") == "deactivating", 5.0)
    finally:
        hub.stop()
        publisher.close()
        transport.close()
        loop.close()
