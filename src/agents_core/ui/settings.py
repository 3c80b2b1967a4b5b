"""``UISettings``: where the UI listens and the limits it keeps."""

from __future__ import annotations

import ipaddress
import os
from pathlib import Path

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
    :param image_format: ``"jpeg"`` or ``"png"`` for raw images sent to clients; ``"raw"``: their rgb8
        pixels in binary frames (no encode; several times the bytes, for loopback), JPEG in JSON frames.
    :param image_preview: the longest side (pixels) of the raw images the live view gets: a larger one
        is sent downscaled by a whole step (640x480 -> 320x240 at the default 320), which cuts the JPEG
        encode about 4x; a client that opens ``/api/outputs?frames=binary&full=1`` gets them whole
        (full resolution on demand; boxes are drawn in the image's own pixels either way). None: always
        full resolution. JSON frames are always whole.
    :param client_queue: frames a WebSocket client may have waiting before it is dropped as too slow.
    :param request_timeout: seconds for a transition or an action to answer.
    :param max_json_bytes: the largest JSON body of an input (uploads are bounded by ``max_upload_bytes``).
    :param max_upload_pixels: the most pixels an uploaded image may have (read from its header, before
        decoding); each side is also bounded by :data:`~.inputs.MAX_UPLOAD_SIDE`.
    :param body_timeout: seconds a request body may take to arrive in full (408 past it).
    :param max_bodies: request bodies read or handled at once (503 past it).
    :param max_clients: WebSocket clients at once (a new one is closed with 1013 past it).
    :param decode_workers: uploads decoded at once (on worker threads, never on the event loop).
    :param session_seconds: how long a login (its session cookie) lasts.
    :param tls_certfile: a PEM certificate to serve HTTPS with (give ``tls_keyfile`` too); meant for
        binding off loopback, where the token would otherwise cross the network in clear.
    :param tls_keyfile: the certificate's PEM private key.
    :param compress_frames: negotiate WebSocket compression (permessage-deflate) with clients that offer
        it. Off by default: it deflates every frame on the event loop, and images (JPEG, or raw pixels on
        loopback) gain little from it for ~5 ms a 640x480 frame on each side (benchmarks/README.md); on
        for a slow link that carries mostly text.
    :param trusted_proxies: addresses of reverse proxies whose ``X-Forwarded-For`` / ``-Proto``
        headers are believed (the client address then comes from them: the login throttle counts
        it). Empty by default: no forwarded header is trusted, not even from loopback, so a local
        client cannot dodge the throttle or lock another address out by naming it.
    """

    host: str = "127.0.0.1"
    port: int = 5001
    token: str | None = field(default=None, repr=False)
    max_upload_bytes: int = 20 * 1024 * 1024
    image_format: str = "jpeg"
    image_preview: int | None = 320
    client_queue: int = 256
    request_timeout: float = 30.0
    max_json_bytes: int = 1024 * 1024
    max_upload_pixels: int = 24_000_000
    body_timeout: float = 15.0
    max_bodies: int = 4
    max_clients: int = 32
    decode_workers: int = 2
    session_seconds: float = 12 * 3600.0
    tls_certfile: str | None = None
    tls_keyfile: str | None = None
    compress_frames: bool = False
    trusted_proxies: tuple[str, ...] = field(default=(), converter=tuple)

    def __attrs_post_init__(self) -> None:
        if self.token is None:
            self.token = os.environ.get(TOKEN_ENV) or None
        self._check_limits()
        self._check_tls()
        for proxy in self.trusted_proxies:
            try:
                ipaddress.ip_network(proxy, strict=False)
            except (TypeError, ValueError):
                raise ConfigError(f"UI trusted_proxies: {proxy!r} is not an IP address or network") from None
        if not isinstance(self.port, int) or not 0 <= self.port <= 65535:
            raise ConfigError(f"UI port must be an int from 0 to 65535, got {self.port!r}")
        if self.image_preview is not None and (isinstance(self.image_preview, bool)
                                               or not isinstance(self.image_preview, int) or self.image_preview < 16):
            raise ConfigError(f"UI image_preview must be None or an int of at least 16 pixels, "
                              f"got {self.image_preview!r}")
        if self.image_format not in ("jpeg", "png", "raw"):
            raise ConfigError(f"UI image_format must be 'jpeg', 'png' or 'raw', got {self.image_format!r}")
        if self.max_upload_bytes <= 0 or self.client_queue <= 0 or not self.request_timeout > 0:
            raise ConfigError("UI max_upload_bytes, client_queue and request_timeout must be positive")
        if self.token is not None and (len(self.token.strip()) < 16 or self.token != self.token.strip()):
            # A token of spaces (or padded with them) is a configuration slip, not a secret.
            raise ConfigError("the UI token must be at least 16 characters long, not counting whitespace, "
                              "and have none around it")
        if not is_loopback(self.host) and self.token is None:
            raise ConfigError(f"the UI binds {self.host!r}, which other machines can reach: give it a token "
                              f"(token=... or the {TOKEN_ENV} environment variable), or bind 127.0.0.1")

    def _check_limits(self) -> None:
        counts = (self.max_json_bytes, self.max_upload_pixels, self.max_bodies, self.max_clients, self.decode_workers)
        if any(not isinstance(n, int) or n <= 0 for n in counts):
            raise ConfigError("UI max_json_bytes, max_upload_pixels, max_bodies, max_clients and decode_workers "
                              "must be positive integers")
        if not self.body_timeout > 0 or not self.session_seconds > 0:
            raise ConfigError("UI body_timeout and session_seconds must be positive")

    def _check_tls(self) -> None:
        given = [f for f in (self.tls_certfile, self.tls_keyfile) if f is not None]
        if len(given) == 1:
            raise ConfigError("UI TLS needs both tls_certfile and tls_keyfile")
        for path in given:
            if not Path(path).is_file():
                raise ConfigError(f"UI TLS file {path!r} does not exist")

    @property
    def tls(self) -> bool:
        """Whether the UI serves HTTPS."""
        return self.tls_certfile is not None
