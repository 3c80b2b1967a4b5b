"""Shared memory for large values (agents_zenoh.shm): a real second process receives them intact.

This process publishes 640x480 rgb8 images and 1 MiB point clouds through the framework's Zenoh
transport; ``tests/agents_zenoh/shm_peer.py`` (a subprocess, stopped by PID) receives them through
the framework and reports each value's digest, and, through a raw session beside it, whether each
sample reached it as a shared-memory block. Loopback endpoints only, multicast scouting off, every
wait bounded.
"""

from __future__ import annotations

import json
import os
import queue
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh")
zshm = pytest.importorskip("zenoh.shm")

import hashlib  # noqa: E402

import numpy as np  # noqa: E402
import zenoh  # noqa: E402

from agents_core import Topic  # noqa: E402
from agents_core.errors import ConfigError  # noqa: E402
from agents_core.messages import Header, ImageMsg, PointCloud2Msg  # noqa: E402
from agents_zenoh import ZenohTransport  # noqa: E402
from agents_zenoh.config import ZenohConfig  # noqa: E402
from agents_zenoh.session import zenoh_config  # noqa: E402
from agents_zenoh.shm import NEVER, ShmPool, shm_payload  # noqa: E402
from tests.conftest import free_tcp_port  # noqa: E402

pytestmark = pytest.mark.zenoh

REPO = Path(__file__).resolve().parents[2]
WAIT = 20.0
CLOUD_DTYPE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4")])


class Peer:
    """The receiving subprocess and the JSON lines it prints."""

    def __init__(self, endpoint: str, namespace: str, shared: bool, log_path: Path) -> None:
        self._log = log_path.open("w")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "tests.agents_zenoh.shm_peer", endpoint, namespace, "on" if shared else "off"],
            cwd=REPO, stdout=subprocess.PIPE, stderr=self._log, text=True,
            env={**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO / "src"), str(REPO)])})
        self.lines: queue.SimpleQueue[str | None] = queue.SimpleQueue()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.put(line.strip())
        self.lines.put(None)

    def next(self, src: str, timeout: float = WAIT) -> dict[str, Any]:
        """The next record from ``src`` (others are kept in ``self.seen``)."""
        while True:
            line = self.lines.get(timeout=timeout)
            if line is None:
                raise AssertionError(f"the peer exited (rc={self.proc.poll()})")
            if line == "READY" or not line.startswith("{"):
                continue
            record: dict[str, Any] = json.loads(line)
            self.seen.append(record)
            if record["src"] == src:
                return record

    seen: list[dict[str, Any]]

    def stop(self) -> None:
        try:
            if self.proc.poll() is None:
                os.kill(self.proc.pid, signal.SIGTERM)
                try:
                    self.proc.wait(timeout=15)
                except subprocess.TimeoutExpired:
                    os.kill(self.proc.pid, signal.SIGKILL)
                    self.proc.wait(timeout=10)
        finally:
            self._reader.join(timeout=5)
            if self.proc.stdout is not None:
                self.proc.stdout.close()
            self._log.close()


def _wait_ready(peer: Peer) -> None:
    while True:
        line = peer.lines.get(timeout=60.0)
        assert line is not None, f"the peer exited before it was ready (rc={peer.proc.poll()})"
        if line == "READY":
            return


@pytest.fixture
def link(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[tuple[ZenohTransport, Peer]]:
    """(publishing transport, receiving peer); param: {"peer_shared": bool, "pool": bytes}, default on and 32 MiB."""
    param = getattr(request, "param", {})
    peer_shared, pool_size = param.get("peer_shared", True), param.get("pool", 32 * 1024 * 1024)
    port = free_tcp_port()
    endpoint, namespace = f"tcp/127.0.0.1:{port}", f"shm_{os.getpid()}_{port}"
    bus = ZenohTransport(mode="peer", listen=[endpoint], connect=[], namespace=namespace, multicast_scouting=False,
                         shm_pool_size=pool_size, shm_threshold=64 * 1024, match_timeout=5.0)
    peer = Peer(endpoint, namespace, peer_shared, tmp_path / "peer.log")
    peer.seen = []
    try:
        _wait_ready(peer)
        yield bus, peer
    finally:
        peer.stop()
        bus.close()


def _image(seq: int) -> ImageMsg:
    pixels = np.random.default_rng(seq).integers(0, 256, (480, 640, 3), dtype=np.uint8)
    return ImageMsg(data=pixels, encoding="rgb8", header=Header(frame_id=str(seq)))


def _cloud(seq: int) -> PointCloud2Msg:
    points = np.zeros(65_536, CLOUD_DTYPE)  # 1 MiB
    rng = np.random.default_rng(1000 + seq)
    for name in CLOUD_DTYPE.names or ():
        points[name] = rng.random(65_536, dtype=np.float32)
    return PointCloud2Msg(points=points, header=Header(frame_id=str(seq)))


def _send(bus: ZenohTransport, peer: Peer, topic: Topic, values: list[Any]) -> list[dict[str, Any]]:
    """Publish each value, waiting (bounded) until the peer has decoded it; the peer's records."""
    pub = bus.create_publisher(topic)
    got = []
    try:
        for value in values:
            pub.publish(value)
            record = peer.next("fw")
            assert record["seq"] == int(value.header.frame_id)
            got.append(record)
    finally:
        pub.close()
    return got


def _digest(arr: np.ndarray[Any, Any]) -> str:
    return hashlib.sha256(arr.tobytes()).hexdigest()


def _raw_shm_flags(peer: Peer, n: int) -> list[bool]:
    """Whether each of the first ``n`` raw samples came as a shared-memory block (waiting for them, bounded)."""
    while sum(r["src"] == "raw" for r in peer.seen) < n:
        peer.next("raw", timeout=5.0)
    return [r["shm"] for r in peer.seen if r["src"] == "raw"]


def test_image_and_point_cloud_reach_another_process_through_shared_memory_intact(
        link: tuple[ZenohTransport, Peer]) -> None:
    bus, peer = link
    images = [_image(i) for i in range(3)]
    clouds = [_cloud(i) for i in range(3)]
    got = _send(bus, peer, Topic("shm/image", "Image"), images)
    got += _send(bus, peer, Topic("shm/cloud", "PointCloud2"), clouds)
    assert [r["digest"] for r in got] == [_digest(v.data) for v in images] + [_digest(v.points) for v in clouds]
    assert got[0]["shape"] == [480, 640, 3] and got[0]["dtype"] == "uint8"
    assert got[3]["shape"] == [65_536] and "intensity" in got[3]["dtype"]
    pool = bus.driver.context.shm
    assert pool is not None and pool.shared == 6 and pool.fallbacks == 0
    # The raw session beside the peer's subscriber saw the samples arrive as shared-memory blocks.
    flags = _raw_shm_flags(peer, 6)
    assert flags and all(flags), flags


@pytest.mark.parametrize("link", [{"pool": 4 * 1024 * 1024}], indirect=True)
def test_a_value_kept_past_its_callback_is_a_copy_the_pool_cannot_overwrite(
        link: tuple[ZenohTransport, Peer]) -> None:
    # 12 images (~11 MB) through a 4 MiB pool: its blocks are reused several times while the peer keeps
    # every received array. Were a kept array a view of a block, later frames would show through it.
    bus, peer = link
    images = [_image(i) for i in range(12)]
    got = _send(bus, peer, Topic("shm/image", "Image"), images)
    assert [r["digest"] for r in got] == [_digest(v.data) for v in images]
    pool = bus.driver.context.shm
    # More values put from the pool than its 4 blocks: blocks were reused while the peer kept every array.
    assert pool is not None and pool.shared + pool.fallbacks == 12 and pool.shared >= 6
    check = bus.create_publisher(Topic("shm/check", "String"))
    try:
        check.publish("check")
        kept = peer.next("kept")
    finally:
        check.close()
    assert kept == {"src": "kept", "n": 12, "intact": True}


@pytest.mark.parametrize("link", [{"peer_shared": False}], indirect=True)
def test_a_peer_without_shared_memory_gets_the_bytes_over_the_network(link: tuple[ZenohTransport, Peer]) -> None:
    # The publisher puts from its pool; Zenoh copies the block into the message for a peer that has no
    # shared memory (the path a peer on another host takes).
    bus, peer = link
    images = [_image(i) for i in range(2)]
    got = _send(bus, peer, Topic("shm/image", "Image"), images)
    assert [r["digest"] for r in got] == [_digest(v.data) for v in images]
    assert bus.driver.context.shm is not None and bus.driver.context.shm.shared == 2
    flags = _raw_shm_flags(peer, 2)
    assert flags and not any(flags), flags


def test_the_off_switch() -> None:
    off = ZenohConfig(shared_memory=False)
    assert json.loads(zenoh_config(off).get_json("transport/shared_memory/enabled")) is False
    assert json.loads(zenoh_config(ZenohConfig()).get_json("transport/shared_memory/enabled")) is True
    port = free_tcp_port()
    bus = ZenohTransport(mode="peer", listen=[f"tcp/127.0.0.1:{port}"], connect=[], multicast_scouting=False,
                         shared_memory=False, shm_threshold=1024)
    try:
        assert bus.driver.context.shm is None
        threshold, wrap = shm_payload(bus.driver.context.shm)
        assert threshold == NEVER and wrap(b"x" * 10) == b"x" * 10
    finally:
        bus.close()
    with pytest.raises(ConfigError, match="shared_memory"):
        ZenohConfig(shared_memory="yes")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="shm_threshold"):
        ZenohConfig(shm_threshold=0)
    # The default: Zenoh's shared-memory transport on, no pool of the transport's own.
    assert ZenohConfig().shared_memory is True and ZenohConfig().shm_threshold is None


def test_a_full_pool_falls_back_to_the_network_path() -> None:
    pool = ShmPool(2 * 1024 * 1024, 1024)
    held = [pool.payload(bytearray(900_000)) for _ in range(2)]
    assert all(isinstance(h, zenoh.ZBytes) for h in held) and pool.shared == 2
    data = bytearray(b"\x07" * 900_000)
    assert pool.payload(data) is data and pool.fallbacks == 1
    assert pool.payload(bytearray(3_000_000)) is not None and pool.fallbacks == 2  # larger than the pool
    del held
