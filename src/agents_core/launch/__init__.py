"""Launching a recipe: the launcher, and one process per component when it asks for them.

:mod:`agents_core.launch.launcher` (:class:`Launcher`: builds the transport, starts the
components, runs events and actions, stops on a signal). ``Launcher.add_pkg(...,
multiprocessing=True)`` runs each component in a process of its own; see
:mod:`agents_core.launch.spec` (what crosses to the child, and how),
:mod:`agents_core.launch.child` (``python -m agents_core.launch.child``) and
:mod:`agents_core.launch.supervisor` (start, crash respawn with backoff, ordered stop).

Each name is imported from its module on first use (PEP 562): a recipe in one process never loads
the process machinery.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..support.lazy import lazy_facade

if TYPE_CHECKING:
    from .launcher import Launcher as Launcher
    from .spec import SPEC_VERSION as SPEC_VERSION
    from .spec import ComponentSpec as ComponentSpec
    from .spec import ValueCodec as ValueCodec
    from .spec import register_value_codec as register_value_codec
    from .supervisor import Supervisor as Supervisor
else:
    __getattr__, __dir__ = lazy_facade(__name__)
