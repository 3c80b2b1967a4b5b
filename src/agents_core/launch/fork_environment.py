"""The launcher's environment for a forked component process: what changed since the fork server started.

A process forked by the fork server (:mod:`.fork_server`) starts with the server's environment,
which is the launcher's as it was when the server started. The launcher's environment may have
changed since (a recipe, or a test harness, set ``ROS_DOMAIN_ID`` before a second ``bringup()``),
so each start of a component (respawns included) computes the changes (:func:`environment_changes`:
variables added or changed, and removed ones as None). They go with the component's spec on its
command pipe, never through the server, and the process applies them before anything else reads
the environment (:meth:`~.spec.ComponentSpec.apply_environment`): it sees the launcher's
environment of the moment it was started, as a spawned process would.

The rule for what a change cannot reach: a variable read when a module the server preloaded was
imported keeps the server's value in a forked process. Those that matter are listed, the core's
in :data:`FIXED_AT_PRELOAD` (numpy's thread pools) and an adapter's in its fork support's
``FIXED_ENVIRONMENT`` (ROS 2: ``RMW_IMPLEMENTATION``, checked when rclpy's library is loaded);
a change to one of them starts the component in a fresh interpreter instead
(:class:`~.fork_server.ForkServerError`, the supervisor's fallback). What the middleware reads
when it is initialised in the component process takes effect: ``ROS_DOMAIN_ID``,
``ROS_AUTOMATIC_DISCOVERY_RANGE`` and the Fast DDS profile (read at ``rclpy.init`` and node
creation), ``ZENOH_*`` (read when the transport opens), ``OTEL_*`` and ``AGENTS_*`` (read at use).
Python's own startup variables (``PYTHON*``) are the server's (the import path travels in the
spec). Changes larger than :data:`MAX_ENVIRONMENT_BYTES` start a fresh interpreter too.
"""

from __future__ import annotations

import importlib
import importlib.util
import json
import os
from collections.abc import Iterable, Mapping

__all__ = ["FIXED_AT_PRELOAD", "MAX_ENVIRONMENT_BYTES", "CannotCarry", "environment_changes", "fixed_environment"]

#: Read when the server imports its base modules (numpy's OpenBLAS pool).
FIXED_AT_PRELOAD = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "GOTO_NUM_THREADS")
#: The most a component's environment changes may take, encoded as JSON.
MAX_ENVIRONMENT_BYTES = 1 << 20


class CannotCarry(ValueError):
    """The changes cannot reach a forked process (a fixed variable changed, or they are too large)."""


def fixed_environment(fork_support: str) -> tuple[str, ...]:
    """The ``FIXED_ENVIRONMENT`` of the fork support module ``fork_support`` (it imports no middleware), if any."""
    try:
        if importlib.util.find_spec(fork_support) is None:
            return ()
        return tuple(map(str, getattr(importlib.import_module(fork_support), "FIXED_ENVIRONMENT", ())))
    except Exception:  # an unusable fork support: the server does not load it either
        return ()


def environment_changes(start: Mapping[str, str], fixed: Iterable[str] = FIXED_AT_PRELOAD,
                        current: Mapping[str, str] | None = None) -> dict[str, str | None]:
    """How ``current`` (this process's environment) differs from ``start``: new values, None for a removed one.

    CannotCarry when a forked process could not apply them (see the module docstring).
    """
    now = dict(os.environ if current is None else current)
    changes: dict[str, str | None] = {k: v for k, v in now.items() if start.get(k) != v}
    changes.update(dict.fromkeys(start.keys() - now.keys()))
    changed_fixed = sorted(set(fixed).intersection(changes))
    if changed_fixed:
        raise CannotCarry(f"{', '.join(changed_fixed)} changed since the fork server started, and the modules it "
                          "preloaded read them when imported")
    size = len(json.dumps(changes))
    if size > MAX_ENVIRONMENT_BYTES:
        raise CannotCarry(f"the environment changed by {size} bytes since the fork server started "
                          f"(more than {MAX_ENVIRONMENT_BYTES})")
    return changes
