"""A router in another process, and transport options that reach it on loopback only."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip("zenoh", reason="needs the zenoh extra")
pytest.importorskip("rosbags", reason="needs the rmw_zenoh extra")
pytest.importorskip("agents_interfaces", reason="needs agents_interfaces")

from agents_core.testing.recipes import open_recipe_transport


@pytest.fixture
def router() -> Iterator[str]:
    """The endpoint of a Zenoh router in a child process: the recipe harness's (ended by PID afterwards)."""
    harness = open_recipe_transport("rmw_zenoh")
    try:
        assert harness.endpoint is not None and harness.router is not None
        yield harness.endpoint
    finally:
        harness.end()


def rmw_options(router: str, **more: Any) -> dict[str, Any]:
    """Transport options: a peer on loopback connected to ``router``, domain 21, multicast off."""
    return {"connect": [router], "listen": ["tcp/127.0.0.1:0"], "domain_id": 21, **more}
