"""Closing a client while its requests are in flight leaves no connection open behind them.

httpx returns the connection of a request that was in flight when the pool closed to the closed
pool, where nothing closes it (a socket left to the garbage collector, a ResourceWarning that
fails whichever test is running then). :class:`BoundedHTTP` closes its pool again when the last
of those requests ends.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest

from agents_core.clients.deadline import BoundedHTTP
from agents_core.testing.helpers import wait_for


class _SlowHandler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"  # keep-alive: the connection outlives one request

    def do_GET(self) -> None:
        time.sleep(0.05)
        body = b"ok"
        self.send_response(200)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, format: str, *args: object) -> None:
        pass


class _CountingServer(ThreadingHTTPServer):
    daemon_threads = True

    def __init__(self) -> None:
        super().__init__(("127.0.0.1", 0), _SlowHandler)
        self.open_connections = 0
        self._lock = threading.Lock()

    def process_request_thread(self, request: object, client_address: object) -> None:
        with self._lock:
            self.open_connections += 1
        try:
            super().process_request_thread(request, client_address)  # type: ignore[arg-type]
        finally:
            with self._lock:
                self.open_connections -= 1


@pytest.fixture
def server() -> Iterator[_CountingServer]:
    srv = _CountingServer()
    thread = threading.Thread(target=srv.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
    thread.start()
    yield srv
    srv.shutdown()
    srv.server_close()
    thread.join(5)


@pytest.mark.parametrize("delay", [0.0, 0.001, 0.005, 0.02, 0.08])
def test_close_while_requests_are_in_flight_leaves_no_connection_open(server: _CountingServer, delay: float) -> None:
    http = BoundedHTTP(f"http://127.0.0.1:{server.server_address[1]}")
    outcomes: list[str] = []

    def ask() -> None:
        try:
            http.request("GET", "/", seconds=5.0, label="test client")
            outcomes.append("answered")
        except Exception as exc:  # cut by close(): expected for some delays
            outcomes.append(type(exc).__name__)

    askers = [threading.Thread(target=ask) for _ in range(4)]
    for t in askers:
        t.start()
    time.sleep(delay)
    http.close()
    for t in askers:
        t.join(10)
    assert len(outcomes) == 4
    # Every connection the requests opened is closed by the client (the server's handler sees the
    # end of its keep-alive connection), without waiting for the garbage collector.
    assert wait_for(lambda: server.open_connections == 0, timeout=5.0), (
        f"{server.open_connections} connection(s) left open after close(); outcomes {outcomes}")
