"""The Foxglove bridge against hostile clients (issue 36, item 5), through real sockets to a real bridge
process serving a 640x480 camera at 30 Hz (``camera_bridge.py``), on memory, Zenoh and ROS 2:

- 20 clients that subscribe to the camera and never read do not grow the process without bound
  (each client's buffer is bounded in bytes, latest frame wins for images);
- a WebSocket from a web page's origin gets no frame; the same client without the header does;
- connections that never finish the HTTP upgrade are closed after ``handshake_timeout``;
- more than ``max_clients`` clients at once are refused with 503.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import json
import os
import socket
import struct
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("foxglove")
pytest.importorskip("google.protobuf")

import websockets

from agents_core.testing.recipes import recipe_environment

from .ws_client import SUBPROTOCOLS, FoxgloveClient

pytestmark = pytest.mark.timeout(180)
REPO = Path(__file__).resolve().parents[2]


class _Bridge:
    def __init__(self, transport: str, *extra: str) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "tests.foxglove.camera_bridge", "--transport", transport,
                                      *extra], cwd=REPO, env=recipe_environment(), stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL, text=True)
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        assert line.startswith("READY"), line
        self.port = int(line.split()[1])
        self.url = f"ws://127.0.0.1:{self.port}"

    def rss_mb(self) -> float:
        with open(f"/proc/{self.proc.pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024
        return 0.0

    def close(self) -> None:
        self.proc.kill()
        self.proc.wait(10)
        if self.proc.stdout is not None:
            self.proc.stdout.close()


@pytest.fixture(params=["memory", "zenoh", "ros2"])
def transport(request: pytest.FixtureRequest) -> str:
    if request.param != "memory":
        from agents_core.testing.pairs import skip_unless_installed  # noqa: PLC0415

        skip_unless_installed(request.param)
    return str(request.param)


@contextlib.contextmanager
def bridge(transport: str, *extra: str) -> Iterator[_Bridge]:
    b = _Bridge(transport, *extra)
    try:
        yield b
    finally:
        b.close()


def _raw_frame(text: str) -> bytes:
    payload = text.encode()
    mask = os.urandom(4)
    masked = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
    n = len(payload)
    head = bytes([0x81]) + (bytes([0x80 | n]) if n < 126 else bytes([0x80 | 126]) + struct.pack("!H", n))
    return head + mask + masked


def _upgrade(port: int, origin: str | None = None) -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", port), timeout=10)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    key = base64.b64encode(os.urandom(16)).decode()
    extra = f"Origin: {origin}\r\n" if origin else ""
    sock.sendall((f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                  f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
                  f"Sec-WebSocket-Protocol: foxglove.sdk.v1, foxglove.websocket.v1\r\n{extra}\r\n").encode())
    return sock


def _read_until_advertised(sock: socket.socket, topic: str) -> int:
    """Read the handshake answer and frames until ``topic`` is advertised; its channel id."""
    buf = b""
    while b"\r\n\r\n" not in buf:
        buf += sock.recv(4096)
    head, buf = buf.split(b"\r\n\r\n", 1)
    assert head.startswith(b"HTTP/1.1 101"), head
    while True:
        while len(buf) < 2 or len(buf) < _frame_len(buf):
            chunk = sock.recv(65536)
            assert chunk, "closed before the advertise"
            buf += chunk
        n = _frame_len(buf)
        frame, buf = buf[:n], buf[n:]
        if frame[0] & 0x0F == 0x1:
            doc = json.loads(frame[_header_len(frame):])
            if doc.get("op") == "advertise":
                for ch in doc["channels"]:
                    if ch["topic"] == topic:
                        return int(ch["id"])


def _header_len(buf: bytes) -> int:
    n = buf[1] & 0x7F
    return 2 + (2 if n == 126 else 8 if n == 127 else 0)


def _frame_len(buf: bytes) -> int:
    if len(buf) < 10:
        return 10 if (buf[1] & 0x7F) >= 126 else 2 + (buf[1] & 0x7F)
    n = buf[1] & 0x7F
    if n == 126:
        n = struct.unpack_from("!H", buf, 2)[0]
    elif n == 127:
        n = struct.unpack_from("!Q", buf, 2)[0]
    return _header_len(buf) + n


def test_twenty_clients_that_stop_reading_do_not_grow_the_recipe(transport: str) -> None:
    with bridge(transport, "--max-clients", "32") as b:
        time.sleep(1.0)
        start_rss = b.rss_mb()
        socks = []
        try:
            for i in range(20):
                sock = _upgrade(b.port)
                channel = _read_until_advertised(sock, "/camera")
                sock.sendall(_raw_frame(json.dumps({"op": "subscribe",
                                                    "subscriptions": [{"id": i + 1, "channelId": channel}]})))
                socks.append(sock)  # and never read again
            peak = start_rss
            deadline = time.monotonic() + 15
            while time.monotonic() < deadline:
                peak = max(peak, b.rss_mb())
                assert peak - start_rss < 600, f"the recipe grew from {start_rss:.0f} to {peak:.0f} MB"
                time.sleep(0.25)
            print(f"{transport}: RSS {start_rss:.0f} MB -> peak {peak:.0f} MB with 20 stalled clients for 15 s")
            # and a client that reads still gets fresh frames
            assert asyncio.run(_frames(b.url, 2.0)) > 5
        finally:
            for sock in socks:
                sock.close()


async def _frames(url: str, seconds: float, **connect: Any) -> int:
    client = await FoxgloveClient.connect(url, **connect) if connect else await FoxgloveClient.connect(url)
    try:
        await client.wait_for_channels(["/camera"])
        await client.subscribe("/camera")
        got = 0
        deadline = time.monotonic() + seconds
        while (left := deadline - time.monotonic()) > 0:
            with contextlib.suppress(asyncio.TimeoutError):
                raw = await asyncio.wait_for(client.ws.recv(), left)
                got += isinstance(raw, bytes)
        return got
    finally:
        await client.close()


async def _origin(url: str, origin: str) -> int | str:
    try:
        async with websockets.connect(url, subprotocols=SUBPROTOCOLS, origin=origin, max_size=None) as ws:  # type: ignore[arg-type]
            got = 0
            with contextlib.suppress(asyncio.TimeoutError):
                while True:
                    raw = await asyncio.wait_for(ws.recv(), 2.0)
                    got += isinstance(raw, bytes)
            return got
    except websockets.InvalidStatus as exc:
        return f"refused {exc.response.status_code}"


def test_a_web_pages_origin_gets_no_frame(transport: str) -> None:
    with bridge(transport, "--allow-origin", "https://app.foxglove.dev") as b:
        assert asyncio.run(_origin(b.url, "http://evil.example")) == "refused 403"
        assert b.proc.poll() is None
        # the origin that is allowed, and a client sending none, are served
        assert asyncio.run(_frames(b.url, 1.5)) > 3
        client = _upgrade(b.port, origin="https://app.foxglove.dev")
        try:
            assert _read_until_advertised(client, "/camera") >= 0
        finally:
            client.close()


def test_connections_that_never_finish_the_upgrade_are_closed(transport: str) -> None:
    with bridge(transport, "--max-clients", "300", "--handshake-timeout", "1.0") as b:
        socks = []
        try:
            for _ in range(200):
                s = socket.create_connection(("127.0.0.1", b.port), timeout=10)
                s.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n")  # and never the rest
                socks.append(s)
            time.sleep(3.0)
            closed = 0
            for s in socks:
                s.settimeout(2.0)
                with contextlib.suppress(OSError):
                    data = s.recv(65536)
                    while data and not data.endswith(b"in time"):
                        more = s.recv(65536)
                        if not more:
                            break
                        data += more
                    closed += 1
            assert closed == 200, f"{200 - closed} half-open connections still held after 3 s"
            assert asyncio.run(_frames(b.url, 1.0)) > 0
        finally:
            for s in socks:
                s.close()


def test_clients_past_max_clients_are_refused(transport: str) -> None:
    with bridge(transport, "--max-clients", "3") as b:
        held = [_upgrade(b.port) for _ in range(3)]
        try:
            for sock in held:
                _read_until_advertised(sock, "/camera")
            extra = socket.create_connection(("127.0.0.1", b.port), timeout=10)
            answer = extra.recv(4096)
            extra.close()
            assert answer.startswith(b"HTTP/1.1 503") and b"max_clients" in answer, answer
        finally:
            for sock in held:
                sock.close()
        time.sleep(0.5)
        assert asyncio.run(_frames(b.url, 1.0)) > 0  # a place is free again
