"""The component runtime: what runs a component, apart from what the component declares.

- :mod:`.component_runtime`: :class:`ComponentRuntime`, one per component (``component.runtime``);
- :mod:`.lifecycle`: the lifecycle state machine;
- :mod:`.health`: health status and fallbacks;
- :mod:`.services`: the ``execute_method`` / ``set_param`` / ``describe`` services;
- :mod:`.worker`: the serial step worker and the periodic timer;
- :mod:`.run_type`: :class:`ComponentRunType`.

Nothing here imports a domain component; components import this package.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..support.lazy import lazy_facade

if TYPE_CHECKING:
    from .component_runtime import ComponentRuntime as ComponentRuntime
    from .health import Health as Health
    from .lifecycle import LifecycleMachine as LifecycleMachine
    from .run_type import ComponentRunType as ComponentRunType
    from .services import ComponentServices as ComponentServices
    from .worker import PeriodicTimer as PeriodicTimer
    from .worker import StepWorker as StepWorker
    from .worker import WorkerStatistics as WorkerStatistics
else:
    __getattr__, __dir__ = lazy_facade(__name__)
