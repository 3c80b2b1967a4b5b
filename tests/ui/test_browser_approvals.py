"""The approval panel in a real browser (Debian's headless Chromium, Playwright): a held call listed
with its time left, settled by the Approve and Deny buttons. Reuses the browser fixtures of
:mod:`tests.ui.test_browser` (skipped, saying why, where Chromium or Playwright is absent)."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("starlette", reason="the ui extra is not installed (pip install 'agents-core[ui]')")

from .approval_parts import HeldCall, arm_with_ui
from .test_browser import TIMEOUT_MS, Page, _open, _shot, browser, page  # noqa: F401  (fixtures)

CARD = '.approval[data-component="arm"][data-action="launch"]'


def test_approve_and_deny_buttons_settle_held_calls(page: Page, tmp_path: Path) -> None:  # noqa: F811
    with arm_with_ui() as (launcher, component):
        _open(page, launcher.ui.url)
        assert page.locator("#approvals-panel").is_hidden()  # nothing waits
        held = HeldCall(launcher, "the moon")
        page.wait_for_selector(CARD, timeout=TIMEOUT_MS)
        card = page.locator(CARD)
        assert '"the moon"' in card.locator("pre.arguments").inner_text()
        assert "asked by cli" in card.inner_text()
        left = float(card.locator(".left").inner_text().split()[0])
        assert 0 <= left <= 5
        _shot(page, tmp_path, "approval-waiting")
        assert component.launches == []
        card.locator('button[data-decide="approve"]').click()
        held.join()
        assert held.error is None and held.result["result"] == "launched at the moon"
        page.wait_for_selector(CARD, state="detached", timeout=TIMEOUT_MS)  # gone from the list
        assert page.locator("#approvals-panel").is_hidden()

        denied = HeldCall(launcher, "mars")
        page.wait_for_selector(CARD, timeout=TIMEOUT_MS)
        page.locator(CARD).locator('button[data-decide="deny"]').click()
        denied.join()
        assert denied.error is not None and "denied by web UI (127.0.0.1)" in denied.error
        page.wait_for_selector(CARD, state="detached", timeout=TIMEOUT_MS)
        assert component.launches == ["the moon"]
