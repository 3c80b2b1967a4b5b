"""``EnvHost``: one Gymnasium environment on a thread of its own, every call to it bounded in time.

Every call to the environment (make, reset, step, render, close) runs on the host's one thread:
MuJoCo's EGL rendering context belongs to the thread that made it, and an environment that hangs
must not hang its caller. :meth:`EnvHost.call` waits at most ``timeout`` seconds; a call that
runs longer raises :class:`EnvHung` and the host is *broken* (its thread is left to finish or not,
as a daemon; the caller makes a new host). An exception the environment raises comes back to
the caller unchanged, and the host stays usable.
"""

from __future__ import annotations

import contextlib
import os
import queue
import threading
from collections.abc import Callable
from typing import Any, TypeVar

__all__ = ["EnvHost", "EnvHung", "make_env", "prepare_rendering"]

T = TypeVar("T")

#: Keyword arguments some environment families take for the size of what ``render()`` returns (gym-aloha's
#: ``observation_width`` only declares its observation's image size; its task renders those at 640x480).
_RENDER_SIZE_KWARGS: dict[str, tuple[str, str]] = {
    "gym_pusht/": ("visualization_width", "visualization_height"),
    "gym_aloha/": ("visualization_width", "visualization_height"),
}


class EnvHung(TimeoutError):
    """An environment call ran past its time limit (the host that ran it is no longer usable)."""


def prepare_rendering() -> None:
    """Render MuJoCo offscreen through EGL unless the user chose another backend (before mujoco is imported)."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    if os.environ["MUJOCO_GL"] == "egl":
        os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


def make_env(env_id: str, kwargs: dict[str, Any], render_size: tuple[int, int] | None) -> Any:
    """``gymnasium.make(env_id, **kwargs)``, rendering ``rgb_array`` frames of ``render_size`` (width, height).

    The environment's package is imported first (``gym_pusht/PushT-v0`` imports ``gym_pusht``,
    which registers it). MuJoCo environments take the size as ``width`` / ``height``; Push-T and
    ALOHA by their own names; an environment that takes none renders at its own size.
    """
    prepare_rendering()
    import importlib  # noqa: PLC0415

    import gymnasium  # noqa: PLC0415 - the sim extra

    if "/" in env_id:
        importlib.import_module(env_id.split("/", 1)[0])
    options = dict(kwargs)
    if render_size is None:
        return gymnasium.make(env_id, **options)
    options.setdefault("render_mode", "rgb_array")
    width, height = render_size
    for prefix, (w_name, h_name) in _RENDER_SIZE_KWARGS.items():
        if env_id.startswith(prefix):
            options.setdefault(w_name, width)
            options.setdefault(h_name, height)
            return gymnasium.make(env_id, **options)
    try:
        return gymnasium.make(env_id, **{"width": width, "height": height, **options})
    except TypeError:  # an environment without a render size of its own
        return gymnasium.make(env_id, **options)


def _close_env(env: Any) -> None:
    """``env.close()``, then free a dm_control physics' rendering contexts here, on the thread that made them.

    (gym-aloha's ``close`` does nothing: its EGL context would otherwise be freed at interpreter exit, from
    another thread, with a traceback.)
    """
    env.close()
    inner = getattr(env.unwrapped, "_env", None)
    physics = getattr(inner, "physics", None) or getattr(env.unwrapped, "physics", None)
    if physics is not None and callable(getattr(physics, "free", None)):
        physics.free()


class EnvHost:
    """Owns one environment on one daemon thread; :meth:`call` runs a function of it, bounded.

    :param factory: makes the environment (runs on the host's thread).
    :param name: names the thread (and errors).
    :param timeout: seconds :meth:`call` waits by default.
    """

    def __init__(self, factory: Callable[[], Any], *, name: str = "env", timeout: float = 30.0) -> None:
        self.name = name
        self.timeout = timeout
        self.broken = False
        self._jobs: queue.SimpleQueue[tuple[Callable[[Any], Any], queue.SimpleQueue[tuple[bool, Any]]] | None] = \
            queue.SimpleQueue()
        self._env: Any = None
        self._thread = threading.Thread(target=self._serve, args=(factory,), name=f"env-host-{name}", daemon=True)
        self._made: queue.SimpleQueue[tuple[bool, Any]] = queue.SimpleQueue()
        self._thread.start()
        self._wait(self._made, timeout, "making the environment")

    def _serve(self, factory: Callable[[], Any]) -> None:
        try:
            self._env = factory()
        except BaseException as exc:
            self._made.put((False, exc))
            return
        self._made.put((True, None))
        while True:
            job = self._jobs.get()
            if job is None:
                return
            func, reply = job
            try:
                reply.put((True, func(self._env)))
            except BaseException as exc:
                reply.put((False, exc))

    def _wait(self, reply: queue.SimpleQueue[tuple[bool, Any]], timeout: float, what: str) -> Any:
        try:
            ok, value = reply.get(timeout=timeout)
        except queue.Empty:
            self.broken = True
            raise EnvHung(f"environment {self.name!r}: {what} took longer than {timeout:g} s") from None
        if not ok:
            raise value
        return value

    def call(self, func: Callable[[Any], T], what: str = "a call", timeout: float | None = None) -> T:
        """``func(env)`` on the host's thread; its result, or its exception; :class:`EnvHung` past ``timeout``."""
        if self.broken:
            raise EnvHung(f"environment {self.name!r} hung before and cannot be used")
        reply: queue.SimpleQueue[tuple[bool, Any]] = queue.SimpleQueue()
        self._jobs.put((func, reply))
        result: T = self._wait(reply, self.timeout if timeout is None else timeout, what)
        return result

    def close(self, timeout: float = 5.0) -> None:
        """Close the environment (and its renderer) on its thread, then end the thread; idempotent."""
        if not self._thread.is_alive():
            return
        if not self.broken and self._env is not None:
            with contextlib.suppress(Exception):  # best effort: the environment may be the broken part
                self.call(_close_env, "closing", timeout)
        self._jobs.put(None)
        if not self.broken:
            self._thread.join(timeout)
