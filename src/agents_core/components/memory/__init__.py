"""The Memory component: a spatio-temporal memory of what the robot observed, on the emem engine.

``from agents_core.components.memory import Memory, MemLayer, MemoryConfig``; each name is imported
on first use, and emem itself only when a Memory configures (``pip install 'agents-core[memory]'``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..._lazy import lazy_facade

if TYPE_CHECKING:
    from .component import Memory
    from .config import MemoryConfig
    from .engine import MemoryStoreError
    from .layers import MemLayer
else:
    __getattr__, __dir__ = lazy_facade(__name__)

__all__ = ["MemLayer", "Memory", "MemoryConfig", "MemoryStoreError"]
