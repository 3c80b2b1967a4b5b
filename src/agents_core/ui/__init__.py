"""A web UI for any recipe, on any transport: a JSON / WebSocket API with a page on top.

In a recipe::

    launcher.enable_ui(inputs=[question, camera], outputs=[answer, detections], port=5001)

Attached to a recipe running elsewhere (another process or machine, on Zenoh or ROS 2)::

    python -m agents_core.ui.attach --transport zenoh --connect tcp/127.0.0.1:7447

Needs the ``ui`` extra (``pip install 'agents-core[ui]'``: Starlette, uvicorn, python-multipart,
Pillow). See ``docs/ui.md`` for the API.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..support.install_hint import install_hint
from ..support.lazy import lazy_facade
from .recipe_view import LocalRecipe as LocalRecipe
from .recipe_view import RecipeView as RecipeView
from .recipe_view import RemoteRecipe as RemoteRecipe
from .settings import TOKEN_ENV as TOKEN_ENV
from .settings import UISettings as UISettings

if TYPE_CHECKING:
    # The server pulls Starlette and uvicorn in: only when asked for, with a clear error without the extra.
    from .server import UIServer as UIServer
else:
    _facade_getattr, __dir__ = lazy_facade(__name__)

    def __getattr__(name: str) -> object:
        try:
            return _facade_getattr(name)
        except ImportError as exc:  # what it loads lazily (the name above, its modules) needs the extra
            raise ImportError(f"the web UI needs the ui extra: {install_hint('ui')} ({exc})") from exc
