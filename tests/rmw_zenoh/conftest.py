"""A router in another process, and transport options that reach it on loopback only."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh", reason="needs the zenoh extra")
pytest.importorskip("rosbags", reason="needs the rmw_zenoh extra")
pytest.importorskip("agents_interfaces", reason="needs agents_interfaces")

HERE = Path(__file__).parent


def free_port() -> int:
    """A free loopback TCP port."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def router() -> Iterator[str]:
    """The endpoint of a Zenoh router running in a child process (ended by PID afterwards)."""
    port = free_port()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    proc = subprocess.Popen([sys.executable, str(HERE / "router.py"), str(port)], stdout=subprocess.PIPE, env=env,
                            text=True)
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == "ready"
        yield f"tcp/127.0.0.1:{port}"
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        if proc.stdout is not None:
            proc.stdout.close()


def rmw_options(router: str, **more: Any) -> dict[str, Any]:
    """Transport options: a peer on loopback connected to ``router``, domain 21, multicast off."""
    return {"connect": [router], "listen": ["tcp/127.0.0.1:0"], "domain_id": 21, **more}
