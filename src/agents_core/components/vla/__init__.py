"""The ``VLA`` component and the parts only it uses.

:mod:`.component` holds :class:`VLA` (a vision-language-action policy driving joints);
:mod:`.config` its :class:`VLAConfig` (re-exported by ``agents_core.config``);
:mod:`.action_chunks` the queue that merges overlapping action chunks; :mod:`.urdf` the joint
limits read from a URDF file or a config dict (``VLAConfig`` validates ``joint_limits`` with it).
``VLA`` is imported on first use (PEP 562), so the config's validation does not load the model
component and its clients.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...support.lazy import lazy_facade

if TYPE_CHECKING:
    from .component import VLA as VLA
    from .config import VLAConfig as VLAConfig
else:
    __getattr__, __dir__ = lazy_facade(__name__)
