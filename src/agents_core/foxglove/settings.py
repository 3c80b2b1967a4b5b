"""``FoxgloveSettings``: where the Foxglove bridge listens, and the rule for binding off loopback."""

from __future__ import annotations

from attrs import define

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
    :param client_backlog: messages the server buffers per client before dropping the oldest.
    :param max_text_chars: the longest text (a Log message, a streamed reply) sent; longer is cut.
    """

    host: str = "127.0.0.1"
    port: int = DEFAULT_PORT
    insecure_remote: bool = False
    queue_depth: int = 1
    client_backlog: int = 256
    max_text_chars: int = 64 * 1024

    def __attrs_post_init__(self) -> None:
        if isinstance(self.port, bool) or not isinstance(self.port, int) or not 0 <= self.port <= 65535:
            raise ConfigError(f"Foxglove port must be an int from 0 to 65535, got {self.port!r}")
        for name in ("queue_depth", "client_backlog", "max_text_chars"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 100_000_000:
                raise ConfigError(f"Foxglove {name} must be a positive int, got {value!r}")
        if not is_loopback(self.host) and self.insecure_remote is not True:
            raise ConfigError(
                f"the Foxglove server would bind {self.host!r}, which other machines can reach, and the "
                "Foxglove WebSocket protocol has no token check: anyone reaching it sees every topic. Bind "
                "127.0.0.1 and use an SSH tunnel (ssh -L 8765:127.0.0.1:8765 robot), or opt in with "
                "insecure_remote=True (agentsctl foxglove --insecure-remote)")
