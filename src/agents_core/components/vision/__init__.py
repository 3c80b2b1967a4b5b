"""The ``Vision`` component and the object tracker only it uses.

:mod:`.component` holds :class:`Vision` (detection on camera frames, tracking, the model
clients or the built-in local detector); :mod:`.config` its :class:`VisionConfig` (re-exported by
``agents_core.config``); :mod:`.tracking` the IoU tracker that follows the
detections of one camera between frames. ``Vision`` is imported on first use (PEP 562), so
importing the tracker alone does not load the model component and its clients.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...support.lazy import lazy_facade

if TYPE_CHECKING:
    from .component import Vision as Vision
    from .config import VisionConfig as VisionConfig
else:
    __getattr__, __dir__ = lazy_facade(__name__)
