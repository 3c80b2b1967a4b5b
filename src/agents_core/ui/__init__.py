"""A web UI for any recipe, on any transport: a JSON / WebSocket API with a page on top.

In a recipe::

    launcher.enable_ui(inputs=[question, camera], outputs=[answer, detections], port=5001)

Attached to a recipe running elsewhere (another process or machine, on Zenoh or ROS 2)::

    python -m agents_core.ui.attach --transport zenoh --connect tcp/127.0.0.1:7447

Needs the ``ui`` extra (``pip install 'agents-core[ui]'``: Starlette, uvicorn, python-multipart,
Pillow). See ``docs/ui.md`` for the API.
"""

from __future__ import annotations

from ..support.install_hint import install_hint
from .recipe_view import LocalRecipe, RecipeView, RemoteRecipe
from .settings import TOKEN_ENV, UISettings

__all__ = ["TOKEN_ENV", "LocalRecipe", "RecipeView", "RemoteRecipe", "UIServer", "UISettings"]


def __getattr__(name: str) -> object:
    # The server pulls Starlette and uvicorn in: only when asked for, with a clear error without the extra.
    if name == "UIServer":
        try:
            from .server import UIServer  # noqa: PLC0415
        except ImportError as exc:
            raise ImportError(f"the web UI needs the ui extra: {install_hint('ui')} ({exc})") from exc
        return UIServer
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
