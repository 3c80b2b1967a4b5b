"""The UI's login on a real uvicorn server (issue 25, item 6): throttled, opaque expiring sessions,
no whitespace tokens, and HTTPS with a certificate and key for use off loopback."""

from __future__ import annotations

import ssl
import subprocess
import time
from pathlib import Path

import httpx
import pytest

pytest.importorskip("uvicorn", reason="the ui extra is not installed (pip install 'agents-core[ui]')")

from agents_core import Launcher
from agents_core.errors import ConfigError
from agents_core.ui import UISettings
from agents_core.ui.app import COOKIE_NAME
from agents_core.ui.sessions import MAX_FAILURES

from .login_parts import TOKEN, token_server


def test_the_cookie_is_an_opaque_expiring_session_not_the_token(running: Launcher) -> None:
    ui = token_server(running)
    try:
        with httpx.Client(base_url=ui.url, timeout=10) as client:
            assert client.get("api/interfaces").status_code == 401
            login = client.post("api/login", json={"token": TOKEN})
            assert login.status_code == 200
            cookie = login.headers["set-cookie"]
            assert TOKEN not in cookie
            assert {"httponly", "samesite=strict", "max-age=43200", "path=/"} <= {
                part.strip().lower() for part in cookie.split(";")}
            session = client.cookies[COOKIE_NAME]
            assert len(session) >= 40
            assert client.get("api/interfaces").status_code == 200
            # a made-up session id is nothing
            stranger = httpx.get(f"{ui.url}api/interfaces", cookies={COOKIE_NAME: "x" * 43}, timeout=10)
            assert stranger.status_code == 401
            assert client.post("api/logout").status_code == 200
            assert httpx.get(f"{ui.url}api/interfaces", cookies={COOKIE_NAME: session}, timeout=10).status_code == 401
    finally:
        ui.stop()


def test_a_session_expires(running: Launcher) -> None:
    ui = token_server(running, session_seconds=1.0)
    try:
        with httpx.Client(base_url=ui.url, timeout=10) as client:
            assert client.post("api/login", json={"token": TOKEN}).status_code == 200
            assert client.get("api/interfaces").status_code == 200
            time.sleep(1.2)
            session = client.cookies[COOKIE_NAME]
        late = httpx.get(f"{ui.url}api/interfaces", cookies={COOKIE_NAME: session}, timeout=10)
        assert late.status_code == 401 and "expired" in late.json()["error"]
    finally:
        ui.stop()


def test_wrong_tokens_are_throttled_per_address(running: Launcher) -> None:
    ui = token_server(running)
    try:
        for _ in range(MAX_FAILURES):
            assert httpx.post(f"{ui.url}api/login", json={"token": "guess" * 4}, timeout=10).status_code == 401
        # now even the right token waits: a guesser cannot tell
        throttled = httpx.post(f"{ui.url}api/login", json={"token": TOKEN}, timeout=10)
        assert throttled.status_code == 429 and "too many wrong tokens" in throttled.json()["error"]
        bearer = httpx.get(f"{ui.url}api/interfaces", headers={"authorization": f"Bearer {TOKEN}"}, timeout=10)
        assert bearer.status_code == 429  # the header is no way around it
    finally:
        ui.stop()


def test_wrong_bearer_tokens_count_too(running: Launcher) -> None:
    ui = token_server(running)
    try:
        for _ in range(MAX_FAILURES):
            reply = httpx.get(f"{ui.url}api/health", headers={"authorization": "Bearer nope-nope-nope-nope"},
                              timeout=10)
            assert reply.status_code == 401
        assert httpx.post(f"{ui.url}api/login", json={"token": TOKEN}, timeout=10).status_code == 429
    finally:
        ui.stop()


@pytest.mark.parametrize("token", [" " * 16, "\t" * 20, "  short-token-x  ", " padded-but-long-enough "])
def test_whitespace_tokens_are_refused_at_configuration(token: str) -> None:
    with pytest.raises(ConfigError, match="not counting whitespace"):
        UISettings(token=token)


def _certificate(folder: Path) -> tuple[str, str]:
    cert, key = folder / "cert.pem", folder / "key.pem"
    command = ["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", str(key), "-out", str(cert),
               "-days", "1", "-subj", "/CN=127.0.0.1", "-addext", "subjectAltName=IP:127.0.0.1"]
    subprocess.run(command, check=True, capture_output=True, timeout=60)
    return str(cert), str(key)


def test_tls_serves_https_with_a_secure_cookie(running: Launcher, tmp_path: Path) -> None:
    import shutil  # noqa: PLC0415

    if shutil.which("openssl") is None:
        pytest.skip("openssl is not installed (it makes the test certificate)")
    cert, key = _certificate(tmp_path)
    ui = token_server(running, tls_certfile=cert, tls_keyfile=key)
    try:
        assert ui.url.startswith("https://127.0.0.1:")
        trusted = ssl.create_default_context(cafile=cert)
        with httpx.Client(base_url=ui.url, verify=trusted, timeout=10) as client:
            login = client.post("api/login", json={"token": TOKEN})
            assert login.status_code == 200 and "secure" in login.headers["set-cookie"].lower()
            assert client.get("api/interfaces").status_code == 200
        with pytest.raises(httpx.TransportError):  # plain HTTP is not served on the TLS port
            httpx.get(ui.url.replace("https", "http"), timeout=5)
    finally:
        ui.stop()


def test_tls_settings_are_checked(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="both"):
        UISettings(tls_certfile=str(tmp_path / "cert.pem"))
    with pytest.raises(ConfigError, match="does not exist"):
        UISettings(tls_certfile=str(tmp_path / "cert.pem"), tls_keyfile=str(tmp_path / "key.pem"))


def test_the_throttle_forgets_after_its_window_and_stays_bounded() -> None:
    from agents_core.ui.sessions import FAILURE_WINDOW, MAX_SESSIONS, Gatekeeper  # noqa: PLC0415

    now = [0.0]
    gate = Gatekeeper(TOKEN, session_seconds=60.0, clock=lambda: now[0])
    for _ in range(MAX_FAILURES):
        assert not gate.check_token("10.0.0.1", "wrong")
    assert gate.throttled("10.0.0.1") > 0 and gate.throttled("10.0.0.2") == 0
    now[0] += FAILURE_WINDOW
    assert gate.throttled("10.0.0.1") == 0
    sessions = [gate.open_session() for _ in range(MAX_SESSIONS + 1)]
    assert not gate.session_valid(sessions[0]) and gate.session_valid(sessions[-1])  # the oldest went first
    now[0] += 61.0
    assert not gate.session_valid(sessions[-1])
