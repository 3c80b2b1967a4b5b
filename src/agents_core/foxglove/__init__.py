"""A live view of any recipe in Foxglove: its topics over the Foxglove WebSocket protocol, on any transport.

In a recipe::

    launcher.enable_foxglove()          # ws://127.0.0.1:8765, every input, output and status topic

For a recipe running elsewhere (Zenoh or ROS 2): ``agentsctl foxglove --transport zenoh``.
Images become ``foxglove.RawImage`` / ``CompressedImage``, detections image annotations on the
image's timeline, odometry and paths 3D poses, text and component status Log lines, anything else
JSON (see :mod:`agents_core.foxglove.feeds`). Needs the ``foxglove`` extra
(``pip install 'agents-core[foxglove]'``: the ``foxglove-sdk`` package). See ``docs/foxglove.md``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..support.install_hint import install_hint
from ..support.lazy import lazy_facade
from .settings import DEFAULT_PORT as DEFAULT_PORT
from .settings import FoxgloveSettings as FoxgloveSettings

if TYPE_CHECKING:
    # The bridge pulls foxglove-sdk in: only when asked for, with a clear error without the extra.
    from .bridge import FoxgloveBridge as FoxgloveBridge
else:
    _facade_getattr, __dir__ = lazy_facade(__name__)

    def __getattr__(name: str) -> object:
        try:
            return _facade_getattr(name)
        except ImportError as exc:  # what it loads lazily (the name above, its modules) needs the extra
            raise ImportError(f"the Foxglove bridge needs the foxglove extra: {install_hint('foxglove')} "
                              f"({exc})") from exc
