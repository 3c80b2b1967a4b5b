"""The processes a component process starts end with it; a stopped component does not outlive its launcher.

Two Linux mechanisms, both set by the component process itself at its start
(:func:`guard_process`):

* ``PR_SET_CHILD_SUBREAPER``: a process the component starts that is orphaned (a ``sh -c 'x &'``,
  a daemon that double-forks) is re-parented to the component process, not to init, so the
  component process can still find every descendant (``/proc/<pid>/task/*/children``) and
  :func:`end_descendants` ends them when it stops: SIGCONT (a stopped one could not act on the
  rest), SIGTERM, and SIGKILL for those still there after ``grace`` seconds.
* ``PR_SET_PDEATHSIG`` with ``SIGCONT``: when the launcher dies, Linux continues the component
  process, so one that was stopped (SIGSTOP, SIGTSTP) runs again and its own launcher watches
  (the end of its command pipe, its parent pid changing) stop it within the exit deadline. A
  SIGTERM sent to a stopped process waits until it is continued, which would never happen.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import time

__all__ = ["descendants", "end_descendants", "guard_process"]

_PR_SET_PDEATHSIG = 1
_PR_SET_CHILD_SUBREAPER = 36


def _prctl(option: int, value: int) -> bool:
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return int(libc.prctl(option, value, 0, 0, 0)) == 0
    except (OSError, AttributeError):
        return False


def guard_process() -> bool:
    """Make this process the subreaper of what it starts and have it continued when its parent dies."""
    reaper = _prctl(_PR_SET_CHILD_SUBREAPER, 1)
    continued = _prctl(_PR_SET_PDEATHSIG, int(signal.SIGCONT))
    return reaper and continued


def _children(pid: int) -> list[int]:
    found: list[int] = []
    with contextlib.suppress(OSError):
        for task in os.listdir(f"/proc/{pid}/task"):
            with contextlib.suppress(OSError), open(f"/proc/{pid}/task/{task}/children") as f:
                found += [int(p) for p in f.read().split()]
    return found


def descendants(pid: int | None = None) -> list[int]:
    """Every live descendant of ``pid`` (default: this process), children first."""
    root = os.getpid() if pid is None else pid
    seen: list[int] = []
    todo = _children(root)
    while todo and len(seen) < 100_000:
        kid = todo.pop(0)
        if kid not in seen and kid != root:
            seen.append(kid)
            todo += _children(kid)
    return seen


def _gone(pid: int) -> bool:
    with contextlib.suppress(ChildProcessError, OSError):
        os.waitpid(pid, os.WNOHANG)  # a child of ours (or an orphan we adopted) that ended: reaped
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] in ("Z", "X")
    except OSError:
        return True


def _signal(pid: int, sig: int) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.kill(pid, sig)


def end_descendants(grace: float = 0.5) -> int:
    """End every process this one started (and theirs); returns how many there were.

    Each gets SIGCONT and SIGTERM; those still there after ``grace`` seconds get SIGKILL.
    """
    pids = descendants()
    if not pids:
        return 0
    for pid in pids:
        _signal(pid, signal.SIGCONT)
        _signal(pid, signal.SIGTERM)
    deadline = time.monotonic() + grace
    while time.monotonic() < deadline:
        if all(_gone(pid) for pid in pids):
            break
        time.sleep(0.02)
    for pid in pids + descendants():  # and what they started meanwhile
        if not _gone(pid):
            _signal(pid, signal.SIGKILL)
    return len(pids)
