"""``UISettings``: where the UI listens and the limits it keeps."""

from __future__ import annotations

import ipaddress
import os

from attrs import define, field

from ..errors import ConfigError

__all__ = ["TOKEN_ENV", "UISettings", "is_loopback"]

#: The environment variable a token is read from when none is given (never from argv).
TOKEN_ENV = "AGENTS_UI_TOKEN"


def is_loopback(host: str) -> bool:
    """Whether ``host`` (a bind address or a Host header's name) is this machine only."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


@define(kw_only=True)
class UISettings:
    """Where the UI listens and what it accepts.

    :param host: the bind address; 127.0.0.1 by default. Any other address needs a ``token``.
    :param port: the TCP port (0: any free port, see ``UIServer.port``).
    :param token: the secret a client must present (``Authorization: Bearer ...`` or the
        ``agents_ui_token`` cookie set by ``POST /api/login``); None reads ``AGENTS_UI_TOKEN``.
        Never shown in reprs or logs.
    :param max_upload_bytes: the largest request body (uploads included).
    :param image_format: ``"jpeg"`` or ``"png"`` for raw images sent to clients.
    :param client_queue: frames a WebSocket client may have waiting before it is dropped as too slow.
    :param request_timeout: seconds for a transition or an action to answer.
    """

    host: str = "127.0.0.1"
    port: int = 5001
    token: str | None = field(default=None, repr=False)
    max_upload_bytes: int = 20 * 1024 * 1024
    image_format: str = "jpeg"
    client_queue: int = 256
    request_timeout: float = 30.0

    def __attrs_post_init__(self) -> None:
        if self.token is None:
            self.token = os.environ.get(TOKEN_ENV) or None
        if not isinstance(self.port, int) or not 0 <= self.port <= 65535:
            raise ConfigError(f"UI port must be an int from 0 to 65535, got {self.port!r}")
        if self.image_format not in ("jpeg", "png"):
            raise ConfigError(f"UI image_format must be 'jpeg' or 'png', got {self.image_format!r}")
        if self.max_upload_bytes <= 0 or self.client_queue <= 0 or not self.request_timeout > 0:
            raise ConfigError("UI max_upload_bytes, client_queue and request_timeout must be positive")
        if self.token is not None and len(self.token) < 16:
            raise ConfigError("the UI token must be at least 16 characters long")
        if not is_loopback(self.host) and self.token is None:
            raise ConfigError(f"the UI binds {self.host!r}, which other machines can reach: give it a token "
                              f"(token=... or the {TOKEN_ENV} environment variable), or bind 127.0.0.1")
