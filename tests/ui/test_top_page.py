"""The UI's top page (``/static/top.html``): every component's status figures, live, with small plots.

The status frames of the output socket carry the figures (``stats``, parsed and bounded); the page
shows a row per component whose numbers and plots move, and sorts by a clicked column (in Debian's
headless Chromium through Playwright, skipped with the reason where either is missing).
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("starlette", reason="the ui extra is not installed (pip install 'agents-core[ui]')")
pytest.importorskip("multipart", reason="python-multipart (the ui extra) is not installed")
from starlette.testclient import TestClient

from agents_core import Launcher
from agents_core.ui import LocalRecipe, UISettings
from agents_core.ui.app import UIState, create_app

from ..telemetry.top_recipe import Echo, Ticker

CHROMIUM = Path("/usr/bin/chromium")


@pytest.fixture
def running() -> Iterator[Launcher]:
    launcher = Launcher("memory")
    launcher.add_pkg(components=[Ticker(rate=20.0), Echo()])
    with launcher:
        yield launcher


def test_status_frames_carry_the_figures_and_the_page_is_served(running: Launcher) -> None:
    state = UIState(LocalRecipe(running.components), running.transport, [], [], UISettings())
    with TestClient(create_app(state), base_url="http://127.0.0.1:5001") as client:
        page = client.get("/static/top.html")
        assert page.status_code == 200 and "/static/top.js" in page.text
        assert client.get("/static/top.js").status_code == 200
        with client.websocket_connect("/api/outputs", headers={"host": "127.0.0.1:5001"}) as ws:
            seen: dict[str, dict[str, Any]] = {}
            deadline = time.monotonic() + 10
            while time.monotonic() < deadline and not all(seen.get(n, {}).get("steps", 0) > 5
                                                          for n in ("ticker", "echo")):
                frame = json.loads(ws.receive_text())
                if frame["kind"] == "status":
                    seen[frame["component"]] = frame["stats"]
            for name in ("ticker", "echo"):
                stats = seen[name]
                assert stats["steps"] > 5 and stats["pid"] > 0 and "p99_ms" in stats and "cpu_pct" in stats


def test_the_page_in_a_browser(running: Launcher, tmp_path: Path) -> None:
    pytest.importorskip("playwright", reason="playwright is not installed (pip install playwright)")
    if not CHROMIUM.is_file():
        pytest.skip("Debian's Chromium is not at /usr/bin/chromium (apt-get install -y chromium)")
    from playwright.sync_api import sync_playwright  # noqa: PLC0415

    from agents_core.ui.server import UIServer  # noqa: PLC0415

    server = UIServer(LocalRecipe(running.components), running.transport, inputs=[], outputs=[],
                      settings=UISettings(port=0))
    server.start()
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=str(CHROMIUM), args=["--no-sandbox"])
            try:
                page = browser.new_page(viewport={"width": 1400, "height": 600})
                page.goto(f"{server.url}static/top.html")
                page.wait_for_selector('tr[data-component="ticker"]', timeout=30_000)
                page.wait_for_selector('tr[data-component="echo"]', timeout=30_000)
                rate = page.locator('tr[data-component="ticker"] td').nth(3)
                first = rate.inner_text()
                page.wait_for_function("() => document.querySelectorAll('#top polyline').length >= 4",
                                       timeout=30_000)
                deadline = time.monotonic() + 15
                while rate.inner_text() == first and time.monotonic() < deadline:
                    time.sleep(0.2)
                assert 10.0 <= float(rate.inner_text()) <= 30.0
                page.click('th[data-key="rate_hz"]')
                page.wait_for_selector('th.sorted[data-key="rate_hz"]', timeout=5_000)
                page.screenshot(path=str(tmp_path / "top.png"))
            finally:
                browser.close()
    finally:
        server.stop()
