"""``FoxgloveSettings``: where the Foxglove bridge listens, and the rule for binding off loopback."""

from __future__ import annotations

from attrs import define, field

from ..errors import ConfigError
from ..ui.settings import is_loopback

__all__ = ["DEFAULT_PORT", "FoxgloveSettings"]

#: Foxglove's usual WebSocket port (what its "Open connection" dialog suggests).
DEFAULT_PORT = 8765


@define(kw_only=True)
class FoxgloveSettings:
    """Where the Foxglove WebSocket server listens and how much it keeps.

    :param host: the bind address; 127.0.0.1 by default.
    :param port: the TCP port (0: any free port, see ``FoxgloveBridge.port``).
    :param insecure_remote: allow a bind address other machines can reach. The web UI requires a
        token there, but the ``foxglove-sdk`` server has no hook to check one (a Foxglove client
        sends no credentials), so any machine that reaches the port would see every served topic.
        Without this opt-in such a bind is refused; prefer an SSH tunnel to a loopback bind.
    :param queue_depth: values of one topic waiting to be converted; a full queue drops the oldest
        (drop-to-latest), counted in ``FoxgloveBridge.statistics()``. The recipe never waits.
    :param client_backlog: messages (of any size) the SDK's server queues per client before dropping
        the oldest; it fills only while the client does not keep up (the guard then stops reading
        for it), so it bounds a stalled client's cost with ``client_buffer_bytes``: keep it small.
    :param max_text_chars: the longest text (a Log message, a streamed reply) sent; longer is cut.
    :param max_clients: Foxglove connections at once (handshakes included); one more is answered 503.
    :param client_buffer_bytes: the bytes waiting for one client; past it an image channel keeps only
        its newest frame and other data drops its oldest message (:mod:`.guard`).
    :param handshake_timeout: seconds a connection has to send its whole WebSocket upgrade request.
    :param allowed_origins: web page origins (``"https://app.foxglove.dev"``) whose WebSocket requests
        are served; a request with any other ``Origin`` header is refused (403). Clients that are not
        web pages (the desktop app, scripts) send none and are served.
    """

    host: str = "127.0.0.1"
    port: int = DEFAULT_PORT
    insecure_remote: bool = False
    queue_depth: int = 1
    client_backlog: int = 4
    max_text_chars: int = 64 * 1024
    max_clients: int = 16
    client_buffer_bytes: int = 8 * 1024 * 1024
    handshake_timeout: float = 5.0
    allowed_origins: tuple[str, ...] = field(default=(), converter=tuple)

    def __attrs_post_init__(self) -> None:
        if isinstance(self.port, bool) or not isinstance(self.port, int) or not 0 <= self.port <= 65535:
            raise ConfigError(f"Foxglove port must be an int from 0 to 65535, got {self.port!r}")
        if isinstance(self.handshake_timeout, bool) or not isinstance(self.handshake_timeout, int | float) \
                or not 0 < self.handshake_timeout <= 3600:
            raise ConfigError(f"Foxglove handshake_timeout must be in (0, 3600] s, got {self.handshake_timeout!r}")
        if not all(isinstance(o, str) and o.startswith(("http://", "https://")) for o in self.allowed_origins):
            raise ConfigError(f"Foxglove allowed_origins must be origins such as 'https://app.foxglove.dev', "
                              f"got {self.allowed_origins!r}")
        for name in ("queue_depth", "client_backlog", "max_text_chars", "max_clients", "client_buffer_bytes"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 100_000_000:
                raise ConfigError(f"Foxglove {name} must be a positive int, got {value!r}")
        if not is_loopback(self.host) and self.insecure_remote is not True:
            raise ConfigError(
                f"the Foxglove server would bind {self.host!r}, which other machines can reach, and the "
                "Foxglove WebSocket protocol has no token check: anyone reaching it sees every topic. Bind "
                "127.0.0.1 and use an SSH tunnel (ssh -L 8765:127.0.0.1:8765 robot), or opt in with "
                "insecure_remote=True (agentsctl foxglove --insecure-remote)")
