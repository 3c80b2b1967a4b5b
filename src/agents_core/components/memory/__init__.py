"""The Memory component: a spatio-temporal memory of what the robot observed, on the emem engine.

``from agents_core.components.memory import Memory, MemLayer, MemoryConfig``; each name is imported
on first use, and emem itself only when a Memory configures (``pip install 'agents-core[memory]'``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...support.lazy import lazy_facade

if TYPE_CHECKING:
    from .component import Memory as Memory
    from .config import MemoryConfig as MemoryConfig
    from .engine import MemoryStoreError as MemoryStoreError
    from .layers import MemLayer as MemLayer
else:
    __getattr__, __dir__ = lazy_facade(__name__)
