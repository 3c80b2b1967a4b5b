"""What the launcher's fork server may import for ROS 2 component processes, and how to fork safely then.

The fork server (:mod:`agents_core.launch.fork_server`) finds this module by name
(``<adapter package>.fork_support``) and imports it before anything else of the adapter; the
module itself imports nothing of ROS 2, so the server can read it with no thread started.

:func:`preload` imports ``rclpy``, this adapter and the generated message modules it uses, and
loads their type-support libraries, so a forked component process only initialises rclpy and
creates its nodes (a fresh interpreter pays about a quarter of a second for these imports).
Nothing here calls ``rclpy.init``: no context, no DDS participant, no executor exists before
the fork (:func:`before_fork` refuses to fork otherwise).

Loading ``rclpy`` loads LTTng-UST (ROS 2's tracing library, through ``tracetools``), whose
constructor starts two listener threads that wait for a tracing session daemon. A fork while
one of them holds LTTng's lock would leave that lock held in the child. LTTng-UST exports the
hooks its own ``liblttng-ust-fork`` wrapper calls around ``fork()`` (``ust_before_fork`` &
co., named ``lttng_ust_*`` since 2.13); :func:`before_fork`, :func:`after_fork_parent` and
:func:`after_fork_child` call them, so the listener threads hold no lock across the fork and
the child starts its own listeners.
"""

from __future__ import annotations

import contextlib
import ctypes
import importlib
import os
import sys
from collections.abc import Callable

__all__ = ["FIXED_ENVIRONMENT", "PRELOAD", "after_fork_child", "after_fork_parent", "before_fork", "preload"]

#: Imported by the fork server: the transport (rclpy, rclpy.node, the executors, the conversions
#: and the message packages they register) and the lifecycle and goal machinery it loads lazily.
PRELOAD = ("agents_ros2.transport", "agents_ros2.lifecycle", "agents_ros2.goals", "agents_ros2.executor",
           "rclpy.action", "rclpy.experimental")
#: Read when :func:`preload` loads rclpy's library (rcl checks the RMW it loaded against them), so a change after
#: the fork server started cannot reach a forked process: the launcher spawns the component instead. What rcl
#: and the RMW read at ``rclpy.init`` and at node creation (``ROS_DOMAIN_ID``, ``ROS_AUTOMATIC_DISCOVERY_RANGE``,
#: ``ROS_STATIC_PEERS``, the Fast DDS profile) is set in the component process before that, and takes effect.
FIXED_ENVIRONMENT = ("RMW_IMPLEMENTATION", "RCL_ASSERT_RMW_ID_MATCHES")
#: sigset_t of glibc on Linux: 1024 bits.
_SIGSET_BYTES = 128

_hooks: tuple[Callable[[int], None], ...] | None = None
_saved_mask = ctypes.create_string_buffer(_SIGSET_BYTES)


def _lttng_libraries() -> set[str]:
    """The paths of the LTTng-UST libraries this process has loaded (one, or none, in practice)."""
    found: set[str] = set()
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as maps:
            for line in maps:
                path = line.rstrip("\n").split(maxsplit=5)[-1]
                name = os.path.basename(path)
                if name.startswith("liblttng-ust") and ".so" in name and not name.startswith(
                        ("liblttng-ust-tracepoint", "liblttng-ust-fork", "liblttng-ust-common", "liblttng-ust-ctl")):
                    found.add(path)
    except OSError:
        pass
    return found


def _find_hooks() -> tuple[Callable[[int], None], ...] | None:
    paths = _lttng_libraries()
    if not paths:
        return None
    if len(paths) > 1:  # each copy has its own threads and lock; the server refuses to vouch for them
        raise RuntimeError(f"several LTTng-UST libraries are loaded ({sorted(paths)}): forking is unsafe")
    path = paths.pop()
    library = ctypes.CDLL(path, mode=os.RTLD_NOLOAD | os.RTLD_GLOBAL)
    for prefix in ("lttng_ust_", "ust_"):
        try:
            hooks = tuple(getattr(library, f"{prefix}{step}") for step in ("before_fork", "after_fork_parent",
                                                                           "after_fork_child"))
        except AttributeError:
            continue
        for hook in hooks:
            hook.argtypes, hook.restype = [ctypes.c_void_p], None
        return hooks
    raise RuntimeError(f"{path} has no fork hooks: forking with its threads running is unsafe")


def _load_type_support() -> None:
    """Load the C type support of every generated message, service and action class imported so far
    (rclpy does it on first use of each, a dlopen of a few libraries: a few milliseconds per process)."""
    for name, module in list(sys.modules.items()):
        if module is None or name.rpartition(".")[2] not in ("msg", "srv", "action"):
            continue
        for value in list(vars(module).values()):
            load = getattr(type(value), "__import_type_support__", None)
            if isinstance(value, type) and load is not None:
                with contextlib.suppress(Exception):  # a type without its library: rclpy says so where used
                    load()


def preload() -> None:
    """Import what a ROS 2 component process needs (see the module docstring); no rclpy.init."""
    global _hooks  # noqa: PLW0603  # found once, in the server, after rclpy loaded LTTng
    for name in PRELOAD:
        importlib.import_module(name)
    _load_type_support()
    _hooks = _find_hooks()


def before_fork() -> None:
    """Called by the server just before it forks; raises when forking is unsafe."""
    rclpy = sys.modules.get("rclpy")
    if rclpy is not None and rclpy.ok():
        raise RuntimeError("rclpy is initialised in the fork server: its context cannot be forked")
    if _hooks is not None:
        _hooks[0](ctypes.addressof(_saved_mask))


def after_fork_parent() -> None:
    """Called by the server after a fork (or a failed one), in the server."""
    if _hooks is not None:
        _hooks[1](ctypes.addressof(_saved_mask))


def after_fork_child() -> None:
    """Called first thing in the forked component process: LTTng starts its listeners again."""
    if _hooks is not None:
        _hooks[2](ctypes.addressof(_saved_mask))
