"""The UI on a real uvicorn server on 127.0.0.1: enable_ui's life cycle, a slow client, attach by discovery."""

from __future__ import annotations

import base64
import contextlib
import json
import os
import socket
import threading
import time
from typing import Any

import httpx
import numpy as np
import pytest

pytest.importorskip("uvicorn", reason="the ui extra is not installed (pip install 'agents-core[ui]')")

from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from agents_core import Launcher
from agents_core.errors import ConfigError
from agents_core.ui import LocalRecipe, UISettings
from agents_core.ui.server import UIServer

from ..conftest import wait_for
from .ui_parts import PICTURE, SHOUTS, WORDS, shouter


def test_enable_ui_serves_while_the_recipe_runs_and_stops_with_it() -> None:
    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter()])
    launcher.enable_ui(port=0)  # no topics named: the recipe's unfed inputs and every output
    with launcher:
        url = launcher.ui.url
        assert url.startswith("http://127.0.0.1:")
        doc = httpx.get(f"{url}api/interfaces", timeout=10).json()
        assert [i["name"] for i in doc["inputs"]] == ["words"]
        assert {o["name"] for o in doc["outputs"]} == {"shouts", "picture"}
        with connect(f"ws://127.0.0.1:{launcher.ui.port}/api/outputs?topics=shouts", open_timeout=10) as ws:
            assert httpx.post(f"{url}api/inputs/words", json={"value": "hi"}, timeout=10).status_code == 200
            frames = [json.loads(ws.recv(timeout=10)) for _ in range(2)]
        assert {"kind": "text", "text": "HI!"}.items() <= next(f for f in frames if f["kind"] == "text").items()
    assert launcher.ui is None
    with pytest.raises(httpx.TransportError):
        httpx.get(f"{url}api/health", timeout=2)


def test_a_port_in_use_is_a_clear_error() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        launcher = Launcher("memory")
        launcher.add_pkg(components=[shouter()])
        launcher.enable_ui(port=taken.getsockname()[1])
        with pytest.raises(ConfigError, match="cannot listen"):
            launcher.start()
    assert launcher.components[0].lifecycle_state.value == "finalized"  # start() undid everything


def _stalled_client(port: int) -> socket.socket:
    """A WebSocket client that completes the handshake and then never reads (a tiny receive buffer)."""
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect(("127.0.0.1", port))
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall((f"GET /api/outputs?topics=picture HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
                  f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n").encode())
    head = b""
    while b"\r\n\r\n" not in head and len(head) < 4096:  # bounded: the 101 answer only
        head += sock.recv(1)
    assert head.startswith(b"HTTP/1.1 101"), head
    return sock


def test_a_client_that_stops_reading_is_dropped_and_others_keep_receiving() -> None:
    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter()])
    with launcher:
        server = UIServer(LocalRecipe(launcher.components), launcher.transport, inputs=[WORDS],
                          outputs=[SHOUTS, PICTURE], settings=UISettings(port=0, client_queue=8)).start()
        try:
            stalled = _stalled_client(server.port)
            publisher = launcher.transport.create_publisher(PICTURE)
            noise = np.random.default_rng(1).integers(0, 255, (480, 640, 3), dtype=np.uint8)  # big JPEGs
            received: list[Any] = []
            with connect(f"ws://127.0.0.1:{server.port}/api/outputs?topics=picture", open_timeout=10,
                         max_size=None) as good:

                def read() -> None:  # the good client reads all the time, on its own thread
                    with contextlib.suppress(ConnectionClosed):
                        for message in good:
                            received.append(message)

                reader = threading.Thread(target=read, daemon=True)
                reader.start()
                assert wait_for(lambda: server.state.hub.client_count == 2, timeout=5)
                for _ in range(400):  # bounded: until the stalled client is dropped
                    publisher.publish(noise)
                    time.sleep(0.02)
                    if server.state.hub.dropped_clients:
                        break
                assert server.state.hub.dropped_clients == 1, "the stalled client was never dropped"
                before = len(received)
                publisher.publish(noise)
                assert wait_for(lambda: len(received) > before, timeout=10), "the reading client was cut off too"
            reader.join(timeout=10)
            assert wait_for(lambda: server.state.hub.client_count == 0, timeout=10)
            assert len(received) > 8, "the reading client got every frame it could"
            health = httpx.get(f"{server.url}api/health", timeout=10).json()
            assert health["dropped_clients"] == 1
            stalled.close()
        finally:
            server.stop()


def test_attach_finds_the_components_by_discovery() -> None:
    from agents_core.ui.attach import attach  # noqa: PLC0415

    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter("loud")])
    with launcher:
        server = attach(launcher.transport, settings=UISettings(port=0))
        try:
            doc = httpx.get(f"{server.url}api/interfaces", timeout=10).json()
            [component] = doc["components"]
            assert component["name"] == "loud" and set(component["actions"]) == {"set_volume", "make_picture"}
            assert [i["name"] for i in doc["inputs"]] == ["words"]
            reply = httpx.post(f"{server.url}api/components/loud/actions/set_volume", json={"args": [2]}, timeout=10)
            assert reply.json()["result"] == 2
        finally:
            server.stop()


def test_enable_ui_is_refused_after_start_and_off_loopback_without_a_token(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("AGENTS_UI_TOKEN", raising=False)
    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter()])
    with pytest.raises(ConfigError, match="give it a token"):
        launcher.enable_ui(host="0.0.0.0")
    with launcher, pytest.raises(ConfigError, match="before the launcher starts"):
        launcher.enable_ui(port=0)


@pytest.mark.ros2
def test_the_ui_attached_over_ros2_to_a_recipe_in_another_process() -> None:
    import subprocess  # noqa: PLC0415
    import sys  # noqa: PLC0415
    from pathlib import Path  # noqa: PLC0415

    from agents_core.testing.pairs import private_ros_environment, skip_unless_installed  # noqa: PLC0415

    skip_unless_installed("ros2", "agents_interfaces")
    from agents_core.transport.registry import resolve_transport  # noqa: PLC0415
    from agents_core.ui.attach import attach  # noqa: PLC0415

    private_ros_environment()
    recipe = subprocess.Popen([sys.executable, "-m", "tests.ui.ui_parts", "--transport", "ros2"],
                              cwd=Path(__file__).resolve().parents[2], stdout=subprocess.PIPE,
                              stderr=subprocess.DEVNULL, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        assert recipe.stdout is not None
        assert recipe.stdout.readline().strip() == "READY", "the recipe process did not start"
        transport = resolve_transport("ros2")
        try:
            # discovery over DDS takes a moment: bounded retries until the component is seen
            assert wait_for(lambda: "shouter" in transport.discover(timeout=1.0).components, timeout=20)
            server = attach(transport, settings=UISettings(port=0))
            try:
                doc = httpx.get(f"{server.url}api/interfaces", timeout=20).json()
                assert [c["name"] for c in doc["components"]] == ["shouter"]
                assert [i["name"] for i in doc["inputs"]] == ["words"]
                with connect(f"ws://127.0.0.1:{server.port}/api/outputs?topics=shouts", open_timeout=10) as ws:
                    text = None
                    for _ in range(20):  # bounded: DDS matching may drop the first values
                        httpx.post(f"{server.url}api/inputs/words", json={"value": "over dds"}, timeout=10)
                        try:
                            frame = json.loads(ws.recv(timeout=1.0))
                        except TimeoutError:
                            continue
                        while frame["kind"] != "text":
                            frame = json.loads(ws.recv(timeout=5.0))
                        text = frame["text"]
                        break
                assert text == "OVER DDS!"
            finally:
                server.stop()
        finally:
            transport.close()
    finally:
        recipe.terminate()
        try:
            recipe.wait(timeout=20)
        except subprocess.TimeoutExpired:
            recipe.kill()
            recipe.wait(timeout=10)
        if recipe.stdout is not None:
            recipe.stdout.close()
