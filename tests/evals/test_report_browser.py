"""The report in a real browser (Debian's headless Chromium, driven by Playwright): it renders, shows the results'
numbers, requests nothing, and runs no script a results file slips in.

Every request the page makes is intercepted (``context.route("**/*")``) and recorded; only the page
itself may be fetched. Screenshots go to ``test-artifacts/evals/``. Skipped, saying why, without
Playwright or ``/usr/bin/chromium`` (``nox -s tests`` installs both where it runs as root with apt).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("playwright", reason="playwright is not installed (pip install playwright)")
from .browser import CHROMIUM, chromium

if not CHROMIUM.is_file():
    pytest.skip("Debian's Chromium is not at /usr/bin/chromium (apt-get install -y chromium)", allow_module_level=True)

from agents_core.evals.compare import compare_runs
from agents_core.evals.report import write_comparison_report, write_report
from agents_core.evals.results import load_results
from agents_core.evals.stats import wilson_interval

from .results_dirs import episode, frame_png, info, make_run, write_dir

ARTIFACTS = Path(__file__).resolve().parents[2] / "test-artifacts" / "evals"
INJECTED = ('<script>window.__pwned = "script"</script><img src="x" onerror="window.__pwned = \'img\'">'
            '<svg onload="window.__pwned = \'svg\'"></svg>')


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    with chromium() as launched:
        yield launched


class _Watched:
    """A page whose every request is recorded and, unless it is the page itself, refused."""

    def __init__(self, browser: Any, allowed: str) -> None:
        self.context = browser.new_context(viewport={"width": 1320, "height": 900})
        self.requests: list[str] = []
        self.console: list[str] = []
        self.context.route("**/*", self._route)
        self.page = self.context.new_page()
        self.page.on("request", lambda request: self.requests.append(request.url))
        self.page.on("console", lambda message: self.console.append(f"{message.type}: {message.text}"))
        self.page.on("pageerror", lambda error: self.console.append(f"pageerror: {error}"))
        self.allowed = allowed

    def _route(self, route: Any) -> None:
        if route.request.url == self.allowed:
            route.continue_()
        else:
            route.abort()

    def outside(self) -> list[str]:
        """The requests for anything but the page (data: URIs are part of the page)."""
        return [url for url in self.requests if url != self.allowed and not url.startswith("data:")]


def _open(browser: Any, path: Path) -> _Watched:
    url = path.resolve().as_uri()
    watched = _Watched(browser, url)
    watched.page.goto(url)
    watched.page.wait_for_load_state("load")
    return watched


def _shot(watched: _Watched, name: str) -> None:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    watched.page.screenshot(path=str(ARTIFACTS / name), full_page=True)


def test_the_watcher_sees_a_page_that_does_reach_out(browser: Any, tmp_path: Path) -> None:
    # The check below must be able to fail: a page of our own that loads an image from the network is caught.
    page = tmp_path / "leaky.html"
    page.write_text('<!DOCTYPE html><p>hi</p><img src="http://127.0.0.1:9/pixel.png">'
                    "<script>window.__pwned = 'yes'</script>")
    watched = _open(browser, page)
    try:
        assert watched.outside() == ["http://127.0.0.1:9/pixel.png"]
        assert watched.page.evaluate("window.__pwned") == "yes"
    finally:
        watched.context.close()


def test_report_renders_its_numbers_loads_nothing_and_runs_no_injected_script(browser: Any, tmp_path: Path) -> None:
    out = tmp_path / "run"
    (out / "frames").mkdir(parents=True)
    lines = []
    for i in range(12):
        success = i % 4 != 1
        frames = []
        if i in (0, 1):
            for k in range(3):
                (out / "frames" / f"ep{i:04d}_{k:02d}.png").write_bytes(frame_png(k, 3, success))
                frames.append(f"frames/ep{i:04d}_{k:02d}.png")
            frames.append("frames/never-written.png")
        reason = INJECTED if i == 1 else None
        lines.append(episode(i, success, seed=40 + i, frames=frames, reason=reason,
                             ended="success" if success else "error"))
    write_dir(out, info(name="hostile <b>name</b>", episodes=12, world=INJECTED, seeds=list(range(40, 52))), lines)
    watched = _open(browser, write_report(out))
    page = watched.page
    try:
        _shot(watched, "report.png")
        results = load_results(out)
        low, high = wilson_interval(results.successes, results.n)
        assert page.text_content("#successes") == f"{results.successes}/{results.n}" == "9/12"
        assert page.text_content("#rate") == "75.0 %"
        assert page.text_content("#interval") == f"{low * 100:.1f} % \u2013 {high * 100:.1f} %"
        assert page.title() == "Evaluation: hostile <b>name</b>"
        rows = page.eval_on_selector_all(
            "table.episodes tbody tr",
            "rows => rows.map(r => [r.querySelector('[data-field=seed]').textContent,"
            " r.querySelector('[data-field=success]').textContent, r.querySelector('[data-field=ended]').textContent])")
        assert rows == [[str(e.seed), "yes" if e.success else "no", e.ended] for e in results.episodes]
        # The injected markup is text on the page, and nothing of it ran or was built.
        assert page.evaluate("window.__pwned") is None
        assert page.evaluate("document.scripts.length") == 0
        assert page.evaluate("document.querySelectorAll('[onerror], [onload]').length") == 0
        assert INJECTED in (page.text_content("table.episodes tbody tr:nth-child(2) [data-field=reason]") or "")
        assert INJECTED in (page.text_content("td[data-field=world]") or "")
        # The frames show (decoded by the browser), the one never written shows as missing.
        sizes = page.eval_on_selector_all(".film img", "imgs => imgs.map(i => [i.complete, i.naturalWidth])")
        assert sizes == [[True, 96]] * 6
        assert page.locator(".film .missing").count() == 2
        # Charts drew: a line per episode.
        assert page.locator("svg.chart polyline").count() == 12
        assert watched.outside() == [], watched.outside()
        assert not [m for m in watched.console if m.startswith(("error", "pageerror"))], watched.console
    finally:
        watched.context.close()


def test_comparison_page_renders_the_verdict(browser: Any, tmp_path: Path) -> None:
    a = make_run(tmp_path / "a", [True] * 17 + [False] * 3, name="expert")
    b = make_run(tmp_path / "b", [True] * 2 + [False] * 18, name="random agent")
    # A hostile reason on the B side too.
    lines = (b / "results.jsonl").read_text().splitlines()
    lines[5] = lines[5].replace('"reason": null', '"reason": "<script>window.__pwned = 1</script>"')
    (b / "results.jsonl").write_text("\n".join(lines) + "\n")
    path = write_comparison_report(a, b, tmp_path / "compare.html")
    watched = _open(browser, path)
    page = watched.page
    try:
        _shot(watched, "compare.png")
        comparison = compare_runs(a, b)
        assert page.text_content("#verdict") == "B is worse than A"
        assert page.text_content("#p-value") == f"p = {comparison.p_value:.4g}"
        assert page.text_content("#run-a #successes") == "17/20" and page.text_content("#run-b #successes") == "2/20"
        assert page.evaluate("window.__pwned") is None and page.evaluate("document.scripts.length") == 0
        assert watched.outside() == []
    finally:
        watched.context.close()


@pytest.mark.parametrize("name", ["eval-report.png", "eval-compare.png"])
def test_docs_screenshots_are_small_pngs(name: str) -> None:
    # Made by `python -m tests.evals.browser docs/images/NAME DIR...` (see tests/evals/browser.py).
    shot = Path(__file__).resolve().parents[2] / "docs" / "images" / name
    assert shot.is_file() and shot.stat().st_size < 300_000
    assert shot.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
