"""Hostile request bodies and uploads against a real uvicorn server (issue 25, item 5).

A decompression-bomb PNG, a 50,000,000 x 1 PNG and a JPEG that claims 60,000 x 60,000 are refused
from their headers; a slow decode never blocks the event loop and at most ``decode_workers`` run at
once; a chunked body that never ends is cut with 408 and its socket closed; past ``max_bodies``
bodies a request is refused at once (503); deep JSON, huge integers and floats are 400s that say so.
"""

from __future__ import annotations

import contextlib
import socket
import struct
import threading
import time
import zlib
from collections.abc import Iterator
from typing import Any

import httpx
import pytest

pytest.importorskip("uvicorn", reason="the ui extra is not installed (pip install 'agents-core[ui]')")

from agents_core import Launcher, Topic
from agents_core.ui import LocalRecipe, UISettings
from agents_core.ui.server import UIServer

from .ui_parts import PICTURE, SHOUTS, WORDS, shouter

CAMERA, LEVEL = Topic("camera", "Image"), Topic("level", "Float64")


def bomb_png(width: int, height: int) -> bytes:
    """A valid, all-black RGB PNG built without ever holding its pixels (a few hundred KB for 49 MP)."""
    packer = zlib.compressobj(9)
    row = b"\x00" * (1 + 3 * width)
    idat = b"".join(packer.compress(row) for _ in range(height)) + packer.flush()

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", idat) + chunk(b"IEND", b"")


def lying_jpeg(width: int, height: int) -> bytes:
    """A JPEG start whose frame header claims ``width`` x ``height`` (the scan data never comes)."""
    sof = b"\xff\xc0" + struct.pack(">HBHHB", 11, 8, height, width, 1) + b"\x01\x11\x00"
    return b"\xff\xd8\xff\xe0" + struct.pack(">H", 16) + b"JFIF\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00" + sof


@pytest.fixture
def server(request: pytest.FixtureRequest) -> Iterator[UIServer]:
    options: dict[str, Any] = getattr(request, "param", {})
    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter()])
    with launcher:
        ui = UIServer(LocalRecipe(launcher.components), launcher.transport, inputs=[WORDS, CAMERA, LEVEL],
                      outputs=[SHOUTS, PICTURE], settings=UISettings(port=0, **options)).start()
        try:
            yield ui
        finally:
            ui.stop()


def _upload(ui: UIServer, data: bytes, topic: str = "camera") -> httpx.Response:
    return httpx.post(f"{ui.url}api/inputs/{topic}", files={"file": ("x.png", data, "image/png")}, timeout=60)


@pytest.mark.parametrize(("picture", "words"), [
    (bomb_png(7000, 7000), "7000x7000 (49000000 pixels)"),
    (bomb_png(50_000_000, 1), "16384 pixels a side"),
    (lying_jpeg(60_000, 60_000), "16384 pixels a side"),
], ids=["49MP-png", "50Mx1-png", "60kx60k-jpeg"])
def test_an_image_too_large_is_refused_from_its_header(server: UIServer, picture: bytes, words: str) -> None:
    started = time.monotonic()
    reply = _upload(server, picture)
    assert reply.status_code == 413, reply.text
    assert words in reply.json()["error"] and "camera" in reply.json()["error"]
    assert time.monotonic() - started < 2.0  # a full decode of these takes seconds and hundreds of MB


def test_a_compressed_image_upload_is_checked_too(server: UIServer) -> None:
    ui = server
    compressed = Topic("packed", "CompressedImage")
    ui.state.inputs[compressed.name] = compressed
    assert _upload(ui, bomb_png(7000, 7000), "packed").status_code == 413
    assert _upload(ui, bomb_png(64, 48), "packed").status_code == 200


@pytest.mark.parametrize("server", [{"decode_workers": 2}], indirect=True)
def test_decoding_is_off_the_event_loop_and_bounded(server: UIServer, monkeypatch: pytest.MonkeyPatch) -> None:
    import agents_core.ui.app as app_module  # noqa: PLC0415

    real = app_module.value_for_topic
    running, most = 0, 0
    lock = threading.Lock()

    def slow_decode(*args: Any, **kwargs: Any) -> Any:  # a decode that takes a while (a large photo)
        nonlocal running, most
        with lock:
            running += 1
            most = max(most, running)
        try:
            time.sleep(1.5)
            return real(*args, **kwargs)
        finally:
            with lock:
                running -= 1

    monkeypatch.setattr(app_module, "value_for_topic", slow_decode)
    codes: list[int] = []
    uploaders = [threading.Thread(target=lambda: codes.append(_upload(server, bomb_png(64, 48)).status_code))
                 for _ in range(3)]
    for thread in uploaders:
        thread.start()
    time.sleep(0.3)
    latencies = []
    for _ in range(5):
        started = time.monotonic()
        assert httpx.get(f"{server.url}api/health", timeout=10).status_code == 200
        latencies.append(time.monotonic() - started)
    for thread in uploaders:
        thread.join(30)
    assert codes == [200, 200, 200]
    assert max(latencies) < 1.0, f"/api/health waited for a decode: {latencies}"
    assert most == 2, f"{most} decodes ran at once; decode_workers is 2"


def _start_chunked(port: int, path: str = "/api/inputs/camera") -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", port))
    sock.sendall((f"POST {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: application/json\r\n"
                  "Transfer-Encoding: chunked\r\n\r\n").encode())
    sock.sendall(b"10\r\n" + b"{" * 16 + b"\r\n")  # some body, then nothing more, ever
    return sock


def _answer(sock: socket.socket, timeout: float) -> bytes:
    """What the server sends until it closes the connection (bounded by ``timeout``)."""
    sock.settimeout(timeout)
    received = b""
    with contextlib.suppress(OSError):
        while chunk := sock.recv(65536):
            received += chunk
    return received


@pytest.mark.parametrize("server", [{"body_timeout": 1.0}], indirect=True)
def test_a_body_that_never_ends_is_cut_and_its_socket_closed(server: UIServer) -> None:
    sock = _start_chunked(server.port)
    started = time.monotonic()
    try:
        answer = _answer(sock, timeout=10)
    finally:
        sock.close()
    assert answer.startswith(b"HTTP/1.1 408"), answer[:200]
    assert b"did not arrive within 1 s" in answer
    assert time.monotonic() - started < 5.0, "the connection was held past the body timeout"
    assert httpx.get(f"{server.url}api/health", timeout=10).json()["refused_bodies"]["time"] == 1


@pytest.mark.parametrize("server", [{"max_bodies": 2, "body_timeout": 30.0}], indirect=True)
def test_bodies_past_the_cap_are_refused_at_once(server: UIServer) -> None:
    stalled = [_start_chunked(server.port) for _ in range(2)]
    try:
        time.sleep(0.3)  # both are being read now
        started = time.monotonic()
        reply = httpx.post(f"{server.url}api/inputs/words", json={"value": "hi"}, timeout=10)
        assert reply.status_code == 503 and "2 requests with a body" in reply.json()["error"]
        assert time.monotonic() - started < 2.0
        assert httpx.get(f"{server.url}api/health", timeout=10).status_code == 200  # no body: never queued
    finally:
        for sock in stalled:
            sock.close()
    # once the stalled clients go away their slots are free again
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        if httpx.post(f"{server.url}api/inputs/words", json={"value": "hi"}, timeout=10).status_code == 200:
            break
        time.sleep(0.1)
    else:
        raise AssertionError("the slots of closed clients were never freed")


@pytest.mark.parametrize(("body", "status", "words"), [
    (b'{"value": ' + b"[" * 100_000 + b"]" * 100_000 + b"}", 400, "nests deeper than 32 levels"),
    (b'{"value": 1' + b"0" * 400 + b"}", 400, "does not fit 64 bits"),
    (b'{"value": 1e400}', 400, "overflows a float"),
    (b'{"value": NaN}', 400, "holds NaN"),
    (b'{"value": 1e39}', 200, ""),  # a finite float: Float64 holds it
    (b'{"value": ' + b'"x", ' * 300_000 + b'"x"}', 413, "at most 1048576"),
], ids=["deep", "huge-int", "huge-float", "nan", "large-float", "too-long"])
def test_hostile_json_is_a_4xx_that_names_the_problem(server: UIServer, body: bytes, status: int, words: str) -> None:
    reply = httpx.post(f"{server.url}api/inputs/level", content=body, headers={"content-type": "application/json"},
                       timeout=30)
    assert reply.status_code == status, reply.text
    if words:
        assert words in reply.json()["error"] and "level" in reply.json()["error"]


def test_hostile_json_in_an_action_or_a_transition_is_a_400(server: UIServer) -> None:
    deep = b'{"kwargs": {"volume": ' + b"[" * 5000 + b"]" * 5000 + b"}}"
    reply = httpx.post(f"{server.url}api/components/shouter/actions/set_volume", content=deep, timeout=10)
    assert reply.status_code == 400 and "deep" in reply.json()["error"]
    huge = b'{"args": [1' + b"0" * 400 + b"]}"
    reply = httpx.post(f"{server.url}api/components/shouter/actions/set_volume", content=huge, timeout=10)
    assert reply.status_code == 400 and "64 bits" in reply.json()["error"]
