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

from ..support.install_hint import install_hint
from .settings import DEFAULT_PORT, FoxgloveSettings

__all__ = ["DEFAULT_PORT", "FoxgloveBridge", "FoxgloveSettings"]


def __getattr__(name: str) -> object:
    # The bridge pulls foxglove-sdk in: only when asked for, with a clear error without the extra.
    if name == "FoxgloveBridge":
        try:
            from .bridge import FoxgloveBridge  # noqa: PLC0415
        except ImportError as exc:
            raise ImportError(f"the Foxglove bridge needs the foxglove extra: {install_hint('foxglove')} ({exc})") \
                from exc
        return FoxgloveBridge
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
