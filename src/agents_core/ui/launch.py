"""What ``Launcher.enable_ui`` runs at start: a UI over the launcher's components and transport."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from ..support.install_hint import install_hint
from .recipe_view import LocalRecipe
from .settings import UISettings

if TYPE_CHECKING:
    from ..components.component_base import Component
    from ..transport.contract import Transport
    from .server import UIServer

__all__ = ["start_ui"]


def start_ui(components: Sequence[Component], transport: Transport, *, inputs: Sequence[Any] | None,
             outputs: Sequence[Any] | None, settings: UISettings) -> UIServer:
    """Start a :class:`~.server.UIServer` for in-process ``components`` (a clear error without the ui extra)."""
    try:
        from .server import UIServer  # noqa: PLC0415
    except ImportError as exc:
        raise ImportError(f"enable_ui() needs the ui extra: {install_hint('ui')} ({exc})") from exc
    view = LocalRecipe(components)
    return UIServer(view, transport, inputs=inputs, outputs=outputs, settings=settings,
                    known_topics=view.topics()).start()
