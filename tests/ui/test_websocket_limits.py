"""WebSocket clients on a real uvicorn server (issue 25, item 5): their number is capped, and a client
dropped as too slow has its TCP connection cut even while it never reads."""

from __future__ import annotations

import socket
import struct
import time

import httpx
import numpy as np
import pytest

pytest.importorskip("uvicorn", reason="the ui extra is not installed (pip install 'agents-core[ui]')")

from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from agents_core import Launcher
from agents_core.ui import LocalRecipe, UISettings
from agents_core.ui.server import UIServer

from ..conftest import wait_for
from .test_server import _stalled_client
from .ui_parts import PICTURE, SHOUTS, WORDS, shouter

_TCP_CLOSE = 7  # Linux's tcp_info state of a connection that is gone (reset or fully closed)


def test_clients_past_the_cap_are_turned_away() -> None:
    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter()])
    with launcher:
        ui = UIServer(LocalRecipe(launcher.components), launcher.transport, inputs=[WORDS], outputs=[SHOUTS],
                      settings=UISettings(port=0, max_clients=2)).start()
        try:
            url = f"ws://127.0.0.1:{ui.port}/api/outputs"
            with connect(url, open_timeout=10), connect(url, open_timeout=10):
                assert wait_for(lambda: ui.state.hub.client_count == 2, timeout=5)
                with connect(url, open_timeout=10) as third, pytest.raises(ConnectionClosed) as closed:
                    third.recv(timeout=5)
                assert closed.value.rcvd is not None and closed.value.rcvd.code == 1013
                assert "too many clients" in closed.value.rcvd.reason
                assert ui.state.hub.client_count == 2
            assert wait_for(lambda: ui.state.hub.client_count == 0, timeout=5)
            with connect(url, open_timeout=10) as again:  # a freed place is taken again
                assert wait_for(lambda: ui.state.hub.client_count == 1, timeout=5)
                again.close()
            health = httpx.get(f"{ui.url}api/health", timeout=10).json()
            assert health["refused_clients"] == 1
        finally:
            ui.stop()


def _tcp_state(sock: socket.socket) -> int:
    return struct.unpack("B", sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_INFO, 8)[:1])[0]


@pytest.mark.skipif(not hasattr(socket, "TCP_INFO"), reason="reads the TCP state through Linux's TCP_INFO")
def test_a_dropped_client_that_never_reads_has_its_connection_cut() -> None:
    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter()])
    with launcher:
        ui = UIServer(LocalRecipe(launcher.components), launcher.transport, inputs=[WORDS],
                      outputs=[SHOUTS, PICTURE], settings=UISettings(port=0, client_queue=4)).start()
        try:
            stalled = _stalled_client(ui.port)
            publisher = launcher.transport.create_publisher(PICTURE)
            noise = np.random.default_rng(2).integers(0, 255, (480, 640, 3), dtype=np.uint8)  # big JPEGs
            for _ in range(400):  # bounded: until it is dropped
                publisher.publish(noise)
                time.sleep(0.02)
                if ui.state.hub.dropped_clients:
                    break
            assert ui.state.hub.dropped_clients == 1
            # it still never reads: the server must cut the connection rather than wait on its full buffer
            assert wait_for(lambda: _tcp_state(stalled) == _TCP_CLOSE, timeout=10), \
                "the dropped client's TCP connection is still open"
            stalled.close()
        finally:
            ui.stop()
