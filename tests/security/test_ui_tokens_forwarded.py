"""The UI's login against hostile clients (issue 36, item 11): a token holding a lone surrogate is a
clean 401, never a 500; ``X-Forwarded-For`` is trusted only from proxies named in the settings, so a
local client can neither dodge the wrong-token throttle nor lock another address out by naming it.
A real uvicorn server on 127.0.0.1, real HTTP requests."""

from __future__ import annotations

import httpx
import pytest

pytest.importorskip("uvicorn", reason="the ui extra is not installed (pip install 'agents-core[ui]')")

from agents_core import Launcher
from agents_core.errors import ConfigError
from agents_core.ui import UISettings
from agents_core.ui.sessions import MAX_FAILURES

from ..ui.login_parts import TOKEN, token_server

pytestmark = pytest.mark.timeout(60)


@pytest.mark.parametrize("token_json", ['"\\ud800"', '"abc\\udfffdef-long-enough"', '"\\ud83d\\ude00x"'])
def test_a_lone_surrogate_token_is_a_clean_401(running: Launcher, token_json: str) -> None:
    ui = token_server(running)
    try:
        reply = httpx.post(f"{ui.url}api/login", content=f'{{"token": {token_json}}}'.encode(),
                           headers={"content-type": "application/json"}, timeout=10)
        assert reply.status_code == 401, (reply.status_code, reply.text)
        assert reply.json()["error"] == "wrong token"
        # non-ASCII bytes in a bearer header (latin-1 on the wire) are a wrong token too
        bearer = httpx.get(f"{ui.url}api/interfaces", headers={"authorization": b"Bearer \xff\xfe\xed-token"},
                           timeout=10)
        assert bearer.status_code == 401
        assert httpx.post(f"{ui.url}api/login", json={"token": TOKEN}, timeout=10).status_code == 200
    finally:
        ui.stop()


def test_x_forwarded_for_does_not_dodge_the_throttle(running: Launcher) -> None:
    ui = token_server(running)
    try:
        for i in range(MAX_FAILURES + 3):
            reply = httpx.post(f"{ui.url}api/login", json={"token": "guess" * 4},
                               headers={"x-forwarded-for": f"198.51.100.{i}"}, timeout=10)
            if i >= MAX_FAILURES:
                assert reply.status_code == 429, f"guess {i + 1} with a made-up X-Forwarded-For: {reply.status_code}"
    finally:
        ui.stop()


def test_x_forwarded_for_cannot_lock_another_address_out(running: Launcher) -> None:
    ui = token_server(running)
    victim = "203.0.113.7"
    try:
        for _ in range(MAX_FAILURES):
            httpx.post(f"{ui.url}api/login", json={"token": "guess" * 4}, headers={"x-forwarded-for": victim},
                       timeout=10)
        # the guesses counted against the sender (loopback), not the address it named
        assert httpx.post(f"{ui.url}api/login", json={"token": TOKEN}, timeout=10).status_code == 429
    finally:
        ui.stop()


def test_a_configured_proxy_is_believed(running: Launcher) -> None:
    ui = token_server(running, trusted_proxies=["127.0.0.1"])
    try:
        for i in range(MAX_FAILURES + 2):
            reply = httpx.post(f"{ui.url}api/login", json={"token": "guess" * 4},
                               headers={"x-forwarded-for": f"198.51.100.{i}"}, timeout=10)
            assert reply.status_code == 401  # each forwarded client has its own count
        assert httpx.post(f"{ui.url}api/login", json={"token": TOKEN}, timeout=10).status_code == 200
    finally:
        ui.stop()


def test_trusted_proxies_are_checked() -> None:
    with pytest.raises(ConfigError, match="trusted_proxies"):
        UISettings(trusted_proxies=["not-an-address"])
    assert UISettings().trusted_proxies == ()
