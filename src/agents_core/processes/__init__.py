"""One process per component: the spec a component is rebuilt from, the child entry point, the supervisor.

``Launcher.add_pkg(..., multiprocessing=True)`` uses this package; see
:mod:`agents_core.processes.spec` (what crosses to the child, and how),
:mod:`agents_core.processes.child` (``python -m agents_core.processes.child``) and
:mod:`agents_core.processes.supervisor` (start, crash respawn with backoff, ordered stop).
"""

from __future__ import annotations

from .spec import SPEC_VERSION, ComponentSpec, ValueCodec, register_value_codec
from .supervisor import Supervisor

__all__ = ["SPEC_VERSION", "ComponentSpec", "Supervisor", "ValueCodec", "register_value_codec"]
