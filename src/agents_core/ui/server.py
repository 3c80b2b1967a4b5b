"""``UIServer``: the UI's uvicorn server on a background thread, started and stopped with a recipe."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
import struct
import threading
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from ..errors import AgentsError, ConfigError
from ..topics import Topic
from .app import UIState, create_app
from .recipe_view import RecipeView, default_topics, topic_from_description
from .settings import UISettings

if TYPE_CHECKING:
    from ..transport.contract import Transport

__all__ = ["MAX_CLIENT_MESSAGE", "UIServer", "resolve_topics"]

logger = logging.getLogger(__name__)

#: The largest WebSocket message a client may send (bytes); a larger one closes its connection (1009).
MAX_CLIENT_MESSAGE = 64 * 1024


def resolve_topics(view: RecipeView, inputs: Sequence[Topic] | None, outputs: Sequence[Topic] | None,
                   known: dict[str, Topic] | None = None) -> tuple[list[Topic], list[Topic]]:
    """The topics the UI shows: those given, else :func:`~.recipe_view.default_topics` of the recipe.

    ``known`` maps names to the recipe's own Topic objects (with their QoS) in-process.
    """
    if inputs is not None and outputs is not None:
        return list(inputs), list(outputs)
    described = []
    for name in view.component_names():
        try:
            described.append(view.describe(name))
        except (AgentsError, KeyError) as exc:  # one component that does not answer: the others still show
            logger.warning("component %r is shown as unavailable: %s", name, exc)
    default_in, default_out = default_topics(described)

    def topics(entries: list[dict[str, Any]]) -> list[Topic]:
        found = [(known or {}).get(e["name"]) or topic_from_description(e) for e in entries]
        return [t for t in found if t is not None]

    return (list(inputs) if inputs is not None else topics(default_in),
            list(outputs) if outputs is not None else topics(default_out))


def _reset(transport: asyncio.Transport) -> None:
    """Close ``transport`` with a TCP reset: a plain close would leave the kernel's send queue (and the
    connection) waiting on a peer that does not read. Nothing happens to a connection already gone
    (its socket object is closed: setsockopt fails, abort does nothing)."""
    sock = transport.get_extra_info("socket")
    if sock is not None:
        with contextlib.suppress(OSError):  # linger 0: close() resets instead of queueing a FIN
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    transport.abort()


class UIServer:
    """Serves the UI of ``view`` over ``transport`` until :meth:`stop`.

    :param inputs: topics the UI may publish on; None: the recipe's inputs that no component feeds.
    :param outputs: topics the UI shows; None: every component output.
    """

    def __init__(self, view: RecipeView, transport: Transport, *, inputs: Sequence[Topic] | None = None,
                 outputs: Sequence[Topic] | None = None, settings: UISettings | None = None,
                 known_topics: dict[str, Topic] | None = None) -> None:
        self.settings = settings or UISettings()
        shown_in, shown_out = resolve_topics(view, inputs, outputs, known_topics)
        self.state = UIState(view, transport, shown_in, shown_out, self.settings)
        self.app = create_app(self.state)
        self._server: Any = None
        self._thread: threading.Thread | None = None
        self._socket: socket.socket | None = None
        self.port: int = self.settings.port

    @property
    def url(self) -> str:
        """Where the page is (the bind address; 127.0.0.1 for a wildcard bind)."""
        host = "127.0.0.1" if self.settings.host in ("0.0.0.0", "::") else self.settings.host
        if ":" in host:
            host = f"[{host}]"
        return f"{'https' if self.settings.tls else 'http'}://{host}:{self.port}/"

    def start(self, timeout: float = 10.0) -> UIServer:
        """Bind and serve on a daemon thread; returns once the server accepts connections."""
        import uvicorn  # noqa: PLC0415  (the ui extra, only when a UI starts)

        family = socket.AF_INET6 if ":" in self.settings.host else socket.AF_INET
        sock = socket.socket(family, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((self.settings.host, self.settings.port))
        except OSError as exc:
            sock.close()
            raise ConfigError(f"the UI cannot listen on {self.settings.host}:{self.settings.port}: {exc}") from exc
        sock.listen(64)
        self._socket = sock
        self.port = int(sock.getsockname()[1])
        # websockets-sansio: no deprecated legacy code path; access log off (paths only, but quiet).
        # ws_max_size: the page sends nothing on its output socket, so a client's message past it is
        # hostile (closed with 1009) rather than read into memory (uvicorn's default allows 16 MiB).
        # ws_per_message_deflate: uvicorn's default (on) deflated each image frame on the event loop.
        config = uvicorn.Config(self.app, log_level="warning", access_log=False, ws="websockets-sansio", loop="asyncio",
                                ws_max_size=MAX_CLIENT_MESSAGE, ws_per_message_deflate=self.settings.compress_frames,
                                lifespan="on", timeout_graceful_shutdown=2, ssl_certfile=self.settings.tls_certfile,
                                ssl_keyfile=self.settings.tls_keyfile,
                                # Forwarded headers only from the proxies named in the settings (none by default).
                                proxy_headers=bool(self.settings.trusted_proxies),
                                forwarded_allow_ips=list(self.settings.trusted_proxies) or None)
        try:
            self._server = uvicorn.Server(config)
            config.load()  # reads the certificate now: a bad one is a clear error here, not a dead thread
        except (OSError, ValueError) as exc:
            sock.close()
            self._socket = None
            self._server = None
            raise ConfigError(f"the UI cannot serve TLS with {self.settings.tls_certfile!r}: {exc}") from exc
        self.state.abort_connection = self._abort_connection
        self._thread = threading.Thread(target=self._server.run, kwargs={"sockets": [sock]},
                                        name="agents-ui", daemon=True)
        self._thread.start()
        deadline = time.monotonic() + timeout
        while not self._server.started:
            if not self._thread.is_alive() or time.monotonic() > deadline:
                self.stop()
                raise ConfigError(f"the UI server did not start on {self.settings.host}:{self.port}")
            time.sleep(0.01)
        logger.info("UI at %s", self.url)
        return self

    def _abort_connection(self, client: tuple[str, int], grace: float = 1.0) -> bool:
        """Cut the TCP connection of ``client`` (host, port), unsent data and all, unless it is gone within
        ``grace`` seconds (a client that reads gets its close frame first). On the event loop."""
        server = self._server
        if server is None:
            return False
        for protocol in list(server.server_state.connections):
            transport = getattr(protocol, "transport", None)
            if getattr(protocol, "client", None) == client and transport is not None:
                asyncio.get_running_loop().call_later(grace, _reset, transport)
                return True
        return False

    def stop(self, timeout: float = 5.0) -> None:
        """Close every client and subscription and stop serving; idempotent."""
        server, self._server = self._server, None
        if server is not None:
            server.should_exit = True
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.join(timeout)
            if thread.is_alive() and server is not None:
                server.force_exit = True
                thread.join(timeout)
        sock, self._socket = self._socket, None
        if sock is not None:
            sock.close()
        self.state.close()

    def __enter__(self) -> UIServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
