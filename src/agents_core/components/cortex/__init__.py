"""``Cortex``: the LLM task planner and executor, and the system monitor.

- :mod:`.component`: the component (an action server for tasks);
- :mod:`.config`: :class:`CortexConfig` (re-exported by ``agents_core.config``);
- :mod:`.tools`: the tools offered to the models and their argument checks;
- :mod:`.planner` / :mod:`.executor`: the two phases of a task;
- :mod:`.dispatch`: where a step goes (Action, ``execute_method``, goal);
- :mod:`.monitor`: the health of the components, from their status topics.

Names are imported on first use, so ``agents_core.config.CortexConfig`` does not load the component.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...support.lazy import lazy_facade

if TYPE_CHECKING:
    from .component import Cortex as Cortex
    from .config import CortexConfig as CortexConfig
else:
    __getattr__, __dir__ = lazy_facade(__name__)
