"""What the UI's login tests share (tests/ui and tests/security): the token, a running Shouter recipe
(the ``running`` fixture: import it into the test module) and a UI server with the token set."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from agents_core import Launcher

from .ui_parts import SHOUTS, WORDS, shouter

__all__ = ["TOKEN", "running", "token_server"]

TOKEN = "correct-horse-battery-staple"


@pytest.fixture
def running() -> Iterator[Launcher]:
    """The Shouter recipe, active on the memory transport."""
    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter()])
    with launcher:
        yield launcher


def token_server(launcher: Launcher, **settings: Any) -> Any:
    """A started UI server (uvicorn, a free port) that needs :data:`TOKEN`; stop it when done."""
    from agents_core.ui import LocalRecipe, UISettings  # noqa: PLC0415  (the ui extra)
    from agents_core.ui.server import UIServer  # noqa: PLC0415

    return UIServer(LocalRecipe(launcher.components), launcher.transport, inputs=[WORDS], outputs=[SHOUTS],
                    settings=UISettings(port=0, token=TOKEN, **settings)).start()
