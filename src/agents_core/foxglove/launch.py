"""What ``Launcher.enable_foxglove`` runs at start: a bridge over the recipe's topics and status topics."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from ..support.install_hint import install_hint
from ..topics import Topic
from ..transport.core import status_topic
from .settings import FoxgloveSettings

if TYPE_CHECKING:
    from ..components.component_base import Component
    from ..transport.contract import Transport
    from .bridge import FoxgloveBridge

__all__ = ["recipe_topics", "start_foxglove"]


def recipe_topics(components: Sequence[Component], topics: Sequence[Topic] | None = None) -> list[Topic]:
    """``topics`` if given, else every input and output of ``components``; plus each one's status topic."""
    chosen: dict[str, Topic] = {}
    for t in topics if topics is not None else [t for c in components for t in (*c.inputs, *c.outputs)]:
        chosen.setdefault(t.name, t)
    for c in components:
        chosen.setdefault(status_topic(c.component_name).name, status_topic(c.component_name))
    return list(chosen.values())


def start_foxglove(components: Sequence[Component], transport: Transport, *, topics: Sequence[Topic] | None,
                   settings: FoxgloveSettings) -> FoxgloveBridge:
    """Start a :class:`~.bridge.FoxgloveBridge` for in-process ``components`` (a clear error without the extra)."""
    try:
        from .bridge import FoxgloveBridge  # noqa: PLC0415
    except ImportError as exc:
        raise ImportError(f"enable_foxglove() needs the foxglove extra: {install_hint('foxglove')} ({exc})") from exc
    return FoxgloveBridge(transport, recipe_topics(components, topics), settings).start()
