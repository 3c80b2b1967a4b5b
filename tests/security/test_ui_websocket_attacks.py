"""Hostile WebSocket clients against the web UI's ``/api/outputs`` (binary frames, latest-wins).

On a real uvicorn server on 127.0.0.1: odd ``frames=`` / ``topics=`` values are refused with a
short reason, a churn of connections that come and go (and some that never read) leaves no
client behind, and a flood of images to a client that never reads keeps only the latest per topic.
"""

from __future__ import annotations

import socket
from urllib.parse import quote

import httpx
import numpy as np
import pytest

pytest.importorskip("uvicorn", reason="the ui extra is not installed (pip install 'agents-core[ui]')")

from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import connect

from agents_core import Launcher
from agents_core.ui import LocalRecipe, UISettings
from agents_core.ui.server import UIServer

from ..conftest import wait_for
from ..ui.ui_parts import PICTURE, SHOUTS, WORDS, shouter


def _server(launcher: Launcher, **settings: object) -> UIServer:
    return UIServer(LocalRecipe(launcher.components), launcher.transport, inputs=[WORDS],
                    outputs=[SHOUTS, PICTURE], settings=UISettings(port=0, **settings)).start()  # type: ignore[arg-type]


@pytest.mark.parametrize("query", [
    "frames=", "frames=BINARY", "frames=binary%00", "frames=" + "b" * 4000, "frames=json&frames=x",
    "frames=%F0%9F%92%A3", "topics=" + quote(",".join(f"t{i}" for i in range(500))),
    "topics=" + quote("\x00\n\r") + "&frames=binary",
])
def test_odd_query_values_are_refused_with_a_short_reason(query: str) -> None:
    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter()])
    with launcher:
        ui = _server(launcher)
        try:
            try:
                with connect(f"ws://127.0.0.1:{ui.port}/api/outputs?{query}", open_timeout=10) as ws, \
                        pytest.raises(ConnectionClosed) as closed:
                    for _ in range(5):
                        ws.recv(timeout=5)
                assert closed.value.rcvd is not None and closed.value.rcvd.code == 1008
                assert len(closed.value.rcvd.reason.encode()) <= 123  # a control frame's limit
            except InvalidStatus as refused:  # a handshake refused outright is fine too
                assert refused.response.status_code in (400, 403, 404)
            assert ui.state.hub.client_count == 0
            assert httpx.get(f"{ui.url}api/health", timeout=10).json()["ok"] is True
        finally:
            ui.stop()


def test_a_churn_of_clients_leaves_none_behind_and_the_cap_holds() -> None:
    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter()])
    with launcher:
        ui = _server(launcher, max_clients=4)
        raw: list[socket.socket] = []
        try:
            url = f"ws://127.0.0.1:{ui.port}/api/outputs?frames=binary"
            for i in range(30):  # connect and vanish, half of them without a close handshake
                with connect(url, open_timeout=10) as ws:
                    if i % 2:
                        ws.socket.shutdown(socket.SHUT_RDWR)
            # half-open TCP connections that never send a handshake do not count as clients
            for _ in range(10):
                raw.append(socket.create_connection(("127.0.0.1", ui.port), timeout=5))
            assert wait_for(lambda: ui.state.hub.client_count == 0, timeout=10)
            with connect(url, open_timeout=10) as a, connect(url, open_timeout=10), connect(url, open_timeout=10), \
                    connect(url, open_timeout=10):
                assert wait_for(lambda: ui.state.hub.client_count == 4, timeout=10)
                with connect(url, open_timeout=10) as fifth, pytest.raises(ConnectionClosed) as closed:
                    fifth.recv(timeout=5)
                assert closed.value.rcvd is not None and closed.value.rcvd.code == 1013
                publisher = launcher.transport.create_publisher(PICTURE)
                for _ in range(200):  # none of them reads: latest-wins keeps the queues short
                    publisher.publish(np.zeros((64, 64, 3), np.uint8))
                for _ in range(20):  # bounded while the hub takes the frames in
                    assert all(c.backlog <= c.depth and len(c.latest) <= 2 for c in ui.state.hub.clients), \
                        [(c.backlog, len(c.latest)) for c in ui.state.hub.clients]
                a.ping().wait(5)
            assert wait_for(lambda: ui.state.hub.client_count == 0, timeout=10)
        finally:
            for sock in raw:
                sock.close()
            ui.stop()
