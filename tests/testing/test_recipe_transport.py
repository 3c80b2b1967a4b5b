""":class:`agents_core.testing.recipes.RecipeTransport` never leaks its router (review s9, finding 8).

On rmw_zenoh (a transport that needs a router): ``close()`` (the contract before ``end()`` existed) stops the
router too, and a transport whose close raises does not keep the router alive, nor the other transports open.
The router is a real process, looked at by its PID.
"""

from __future__ import annotations

import pytest

from agents_core.errors import TransportClosedError, TransportError
from agents_core.testing.helpers import wait_for
from agents_core.testing.pairs import missing_requirement
from agents_core.testing.recipes import open_recipe_transport
from agents_core.topics import Topic
from agents_core.transport import MemoryTransport

pytestmark = [pytest.mark.zenoh, pytest.mark.timeout(120)]


class _FailsToClose(MemoryTransport):
    """A transport whose close raises (after it closed)."""

    def close(self) -> None:
        super().close()
        raise TransportError("closing failed")


def _router_gone(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] in ("Z", "X")
    except OSError:
        return True


@pytest.fixture(autouse=True)
def _rmw_zenoh() -> None:
    reason = missing_requirement("rmw_zenoh")
    if reason is not None:
        pytest.skip(reason)


def test_close_stops_the_router() -> None:
    harness = open_recipe_transport("rmw_zenoh")
    assert harness.router is not None
    pid = harness.router.proc.pid
    try:
        harness.open_asker()
        harness.close()
        assert wait_for(lambda: _router_gone(pid), timeout=20.0), "close() leaked it"
    finally:
        harness.end()  # the same as close(), again: nothing left to do


def test_a_transport_that_fails_to_close_leaks_neither_the_router_nor_the_others() -> None:
    harness = open_recipe_transport("rmw_zenoh")
    assert harness.router is not None
    pid = harness.router.proc.pid
    try:
        asker = harness.open_asker()
        harness._opened.append(_FailsToClose())  # the newest: closed first
        with pytest.raises(TransportError, match="closing failed"):
            harness.end()
        assert wait_for(lambda: _router_gone(pid), timeout=20.0), "end() leaked it"
        with pytest.raises(TransportClosedError):
            asker.create_publisher(Topic("after/close", "String"))
    finally:
        if not _router_gone(pid):
            harness.router.stop()
