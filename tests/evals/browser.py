"""Debian's headless Chromium through Playwright, for the report's browser tests and the docs screenshot.

``python -m tests.evals.browser OUT.png [DIR | DIR_A DIR_B]`` writes a screenshot of the top of a
report: of DIR's report, of the comparison of DIR_A and DIR_B, or with neither, of a hand-written
Reacher evaluation. The images of docs/evaluate-report.md are of a real run::

    python -m agents_core.demo eval --episodes 20 --out eval-demo     # the sim extra
    python -m tests.evals.browser docs/images/eval-report.png eval-demo/expert
    python -m tests.evals.browser docs/images/eval-compare.png eval-demo/expert eval-demo/random
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

CHROMIUM = Path("/usr/bin/chromium")
#: No sandbox (containers run as root), no GPU, and nothing of its own on the network.
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--no-first-run"]


@contextmanager
def chromium() -> Iterator[Any]:
    """A launched Chromium browser (closed on exit)."""
    from playwright.sync_api import sync_playwright  # noqa: PLC0415 - only where a browser is used

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            yield browser
        finally:
            browser.close()


def screenshot(report: Path, png: Path, *, width: int = 1320, max_height: int = 1700) -> Path:
    """A PNG of the top of ``report`` (``max_height`` pixels at most), reduced to 256 colours when Pillow is there."""
    with chromium() as browser:
        page = browser.new_page(viewport={"width": width, "height": 900})
        page.goto(report.resolve().as_uri())
        height = min(max_height, int(page.evaluate("document.documentElement.scrollHeight")))
        page.screenshot(path=str(png), full_page=True, clip={"x": 0, "y": 0, "width": width, "height": height})
    try:
        from PIL import Image  # noqa: PLC0415 - optional: only makes the file smaller
    except ImportError:
        return png
    with Image.open(png) as image:
        image.convert("RGB").quantize(colors=256).save(png, optimize=True)
    return png


def main(argv: list[str]) -> None:
    """Write a screenshot to ``argv[0]``: of the report of ``argv[1]``, or the comparison of ``argv[1:3]``."""
    from agents_core.evals.report import write_comparison_report, write_report  # noqa: PLC0415

    from .results_dirs import make_run  # noqa: PLC0415

    target = Path(argv[0] if argv else "docs/images/eval-report.png").resolve()
    target.parent.mkdir(parents=True, exist_ok=True)
    if len(argv) > 2:
        with tempfile.TemporaryDirectory() as tmp:
            page = write_comparison_report(Path(argv[1]), Path(argv[2]), Path(tmp) / "compare.html")
            screenshot(page, target, max_height=1500)
        print(f"{target}: {target.stat().st_size} bytes")
        return
    if len(argv) > 1:
        screenshot(write_report(Path(argv[1])), target)
        print(f"{target}: {target.stat().st_size} bytes")
        return
    work = Path(tempfile.mkdtemp(prefix="eval-report-"))
    here = Path.cwd()
    try:
        os.chdir(work)  # the page shows the results directory as given: a short relative one
        outcomes = [i not in (3, 8, 14) for i in range(20)]
        out = make_run(Path("evals/reacher-expert"), outcomes, name="reacher-expert", seeds=list(range(100, 120)))
        screenshot(write_report(out), target)
    finally:
        os.chdir(here)
        shutil.rmtree(work, ignore_errors=True)
    print(f"{target}: {target.stat().st_size} bytes")


if __name__ == "__main__":
    main(sys.argv[1:])
