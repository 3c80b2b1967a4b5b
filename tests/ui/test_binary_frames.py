"""Binary image frames on a real uvicorn server (issue 29, item 3): their format, latest-wins for a client
that never reads (bounded, drops counted), and hostile messages from the client side."""

from __future__ import annotations

import base64
import io
import os
import socket
import time

import httpx
import numpy as np
import pytest

pytest.importorskip("uvicorn", reason="the ui extra is not installed (pip install 'agents-core[ui]')")

from PIL import Image as PILImage
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from agents_core import Launcher, Topic
from agents_core.transport import MemoryTransport
from agents_core.ui import LocalRecipe, UISettings
from agents_core.ui.binary_frames import HEADER, pack_image, unpack
from agents_core.ui.server import MAX_CLIENT_MESSAGE, UIServer

from ..conftest import wait_for
from .ui_parts import PICTURE, SHOUTS, WORDS, shouter


def _server(launcher: Launcher, **settings: object) -> UIServer:
    return UIServer(LocalRecipe(launcher.components), launcher.transport, inputs=[WORDS],
                    outputs=[SHOUTS, PICTURE], settings=UISettings(port=0, **settings)).start()  # type: ignore[arg-type]


def _next_binary(ws: object, limit: int = 10) -> bytes:
    for _ in range(limit):  # bounded: status frames (text) come first
        message = ws.recv(timeout=10)  # type: ignore[attr-defined]
        if isinstance(message, bytes):
            return message
    raise AssertionError(f"no binary frame in {limit} frames")


def test_the_header_round_trips_and_bad_frames_are_refused() -> None:
    frame = pack_image(7, "image/jpeg", b"\xff\xd8jpeg", 640, 480, 123)
    assert frame is not None and len(frame) == HEADER.size + 6 == 30
    parsed = unpack(frame)
    assert (parsed.version, parsed.encoding, parsed.topic_id, parsed.width, parsed.height, parsed.stamp_ns,
            parsed.payload) == (1, 1, 7, 640, 480, 123, b"\xff\xd8jpeg")
    assert unpack(pack_image(0, "image/png", b"x", None, None, None) or b"").stamp_ns is None
    assert pack_image(0, "image/webp", b"x", 1, 1, None) is None  # sent as a JSON frame instead
    assert pack_image(70_000, "image/jpeg", b"x", 1, 1, None) is None
    with pytest.raises(ValueError, match="at least"):
        unpack(frame[:10])
    with pytest.raises(ValueError, match="payload bytes"):
        unpack(frame + b"extra")
    with pytest.raises(ValueError, match="version"):
        unpack(b"\x02" + frame[1:])


def test_a_binary_client_gets_images_as_binary_frames_and_text_as_json() -> None:
    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter()])
    with launcher:
        ui = _server(launcher)
        try:
            outputs = httpx.get(f"{ui.url}api/interfaces", timeout=10).json()["outputs"]
            ids = {o["name"]: o["id"] for o in outputs}
            assert sorted(ids.values()) == [0, 1]
            with connect(f"ws://127.0.0.1:{ui.port}/api/outputs?frames=binary", open_timeout=10,
                         max_size=None) as ws:
                assert wait_for(lambda: ui.state.hub.client_count == 1, timeout=5)
                ramp = np.linspace(0, 255, 64, dtype=np.uint8)  # smooth: JPEG keeps it close
                pixels = np.stack([np.tile(ramp, (48, 1)), np.tile(ramp[::-1], (48, 1)),
                                   np.full((48, 64), 90, np.uint8)], axis=2)
                launcher.transport.create_publisher(PICTURE).publish(pixels)
                frame = unpack(_next_binary(ws))
                launcher.transport.create_publisher(WORDS).publish("hi")
                texts = [ws.recv(timeout=10) for _ in range(3)]
            assert (frame.encoding, frame.topic_id, frame.width, frame.height) == (1, ids["picture"], 64, 48)
            decoded = np.asarray(PILImage.open(io.BytesIO(frame.payload)).convert("RGB"))
            assert decoded.shape == (48, 64, 3) and np.abs(decoded.astype(int) - pixels).mean() < 8
            assert any(isinstance(t, str) and '"text":"HI!"' in t for t in texts), texts
        finally:
            ui.stop()


def test_raw_image_format_sends_the_exact_pixels() -> None:
    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter()])
    with launcher:
        ui = _server(launcher, image_format="raw")
        try:
            with connect(f"ws://127.0.0.1:{ui.port}/api/outputs?topics=picture&frames=binary", open_timeout=10,
                         max_size=None) as ws, \
                 connect(f"ws://127.0.0.1:{ui.port}/api/outputs?topics=picture", open_timeout=10,
                         max_size=None) as json_ws:
                assert wait_for(lambda: ui.state.hub.client_count == 2, timeout=5)
                pixels = np.random.default_rng(4).integers(0, 255, (30, 40, 3), dtype=np.uint8)
                launcher.transport.create_publisher(PICTURE).publish(pixels)
                frame = unpack(_next_binary(ws))
                as_json = next(m for m in (json_ws.recv(timeout=10) for _ in range(5)) if '"kind":"image"' in m)
            assert (frame.encoding, frame.width, frame.height) == (3, 40, 30)
            assert np.array_equal(np.frombuffer(frame.payload, np.uint8).reshape(30, 40, 3), pixels)
            assert isinstance(as_json, str) and '"mime":"image/jpeg"' in as_json  # JSON clients: JPEG
        finally:
            ui.stop()


def _stalled_binary_client(port: int) -> socket.socket:
    """A binary-frames WebSocket client (full resolution: big frames) that completes the handshake and then
    never reads."""
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect(("127.0.0.1", port))
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall((f"GET /api/outputs?topics=picture&frames=binary&full=1 HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n"
                  f"Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                  "Sec-WebSocket-Version: 13\r\n\r\n").encode())
    head = b""
    while b"\r\n\r\n" not in head and len(head) < 4096:  # bounded: the 101 answer only
        head += sock.recv(1)
    assert head.startswith(b"HTTP/1.1 101"), head
    return sock


def test_a_binary_client_that_never_reads_keeps_only_the_latest_frame() -> None:
    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter()])
    with launcher:
        ui = _server(launcher, client_queue=4)
        stalled = _stalled_binary_client(ui.port)
        try:
            assert wait_for(lambda: ui.state.hub.client_count == 1, timeout=5)
            (client,) = ui.state.hub.clients  # the server's own view of that client
            publisher = launcher.transport.create_publisher(PICTURE)
            noise = np.random.default_rng(5).integers(0, 255, (480, 640, 3), dtype=np.uint8)  # big JPEGs
            backlog = []
            for _ in range(150):  # far more than the client queue and the socket buffers hold
                publisher.publish(noise)
                time.sleep(0.005)
                backlog.append((client.queue.qsize(), len(client.latest)))
            assert wait_for(lambda: ui.state.hub.dropped_frames >= 100, timeout=10), ui.state.hub.dropped_frames
            # bounded: the component's status frame it never read, and the newest image (one per topic)
            assert max(q for q, _ in backlog) <= 2 and max(n for _, n in backlog) <= 1, backlog[-5:]
            assert client.dropped_frames == ui.state.hub.dropped_frames
            assert ui.state.hub.dropped_clients == 0, "images alone never make a binary client 'too slow'"
            health = httpx.get(f"{ui.url}api/health", timeout=10).json()
            assert health["dropped_frames"] >= 100 and health["dropped_clients"] == 0
            # every image is counted once, sent (or waiting) or replaced; frames_sent also has the
            # component's status frame(s) when one went out before the client stalled (not always)
            counted = ui.state.hub.frames_sent + ui.state.hub.dropped_frames
            assert 150 <= counted <= 150 + 3, counted
            stalled.close()
            assert wait_for(lambda: ui.state.hub.client_count == 0, timeout=10)
        finally:
            stalled.close()  # also when an assert above failed: a leaked socket fails the whole run
            ui.stop()


def test_hostile_messages_from_the_client_side() -> None:
    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter()])
    with launcher:
        ui = _server(launcher)
        try:
            base = f"ws://127.0.0.1:{ui.port}/api/outputs"
            with connect(f"{base}?frames=bogus", open_timeout=10) as bad, pytest.raises(ConnectionClosed) as closed:
                bad.recv(timeout=5)
            assert closed.value.rcvd is not None and closed.value.rcvd.code == 1008
            with connect(f"{base}?frames=binary", open_timeout=10, max_size=None) as good, \
                 connect(f"{base}?frames=binary", open_timeout=10, max_size=None) as hostile:
                assert wait_for(lambda: ui.state.hub.client_count == 2, timeout=5)
                # garbage that the server must ignore: not parsed, not answered, not fatal
                for junk in (b"\x00" * 100, b"\x01\x01\xff\xff" + os.urandom(200), "{not json", '{"kind":"image"}'):
                    hostile.send(junk)
                hostile.ping().wait(5)  # the server read all of it and still answers
                # past the size bound: the connection is closed (1009) before it is read into memory
                hostile.send(b"\x00" * (MAX_CLIENT_MESSAGE + 1))
                with pytest.raises(ConnectionClosed) as too_big:
                    for _ in range(20):  # bounded: status frames may come first
                        hostile.recv(timeout=5)
                assert too_big.value.rcvd is not None and too_big.value.rcvd.code == 1009
                launcher.transport.create_publisher(PICTURE).publish(np.zeros((8, 8, 3), np.uint8))
                assert unpack(_next_binary(good)).width == 8, "the other client kept receiving"
            assert wait_for(lambda: ui.state.hub.client_count == 0, timeout=10)
            assert httpx.get(f"{ui.url}api/health", timeout=10).json()["ok"] is True
        finally:
            ui.stop()


def test_a_topic_id_names_each_output_in_order() -> None:
    ids = Topic("a", "Image"), Topic("b", "String")
    transport = MemoryTransport()
    ui = UIServer(LocalRecipe([]), transport, inputs=[], outputs=list(ids), settings=UISettings(port=0)).start()
    try:
        outputs = httpx.get(f"{ui.url}api/interfaces", timeout=10).json()["outputs"]
    finally:
        ui.stop()
        transport.close()
    assert [(o["name"], o["id"]) for o in outputs] == [("a", 0), ("b", 1)]


def test_websocket_compression_is_off_unless_asked_for() -> None:
    """permessage-deflate (which the websockets client and browsers offer) deflated every image frame on
    the event loop: ~5 ms a 640x480 frame on each side. Off by default, negotiated with compress_frames."""
    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter()])
    with launcher:
        for compress in (False, True):
            ui = _server(launcher, compress_frames=compress)
            try:
                with connect(f"ws://127.0.0.1:{ui.port}/api/outputs?topics=picture&frames=binary",
                             open_timeout=10, max_size=None) as ws:
                    assert ws.response is not None
                    offered = ws.request.headers.get("Sec-WebSocket-Extensions") if ws.request else None
                    assert offered is not None and "permessage-deflate" in offered  # the client offers it
                    agreed = ws.response.headers.get("Sec-WebSocket-Extensions") or ""
                    assert ("permessage-deflate" in agreed) is compress, (compress, agreed)
                    hub = ui.state.hub
                    assert wait_for(lambda: hub.client_count == 1, timeout=5)  # noqa: B023  (called here)
                    pixels = np.random.default_rng(5).integers(0, 255, (30, 40, 3), dtype=np.uint8)
                    launcher.transport.create_publisher(PICTURE).publish(pixels)
                    frame = unpack(_next_binary(ws))  # frames arrive either way
                    assert (frame.width, frame.height) == (40, 30)
            finally:
                ui.stop()
