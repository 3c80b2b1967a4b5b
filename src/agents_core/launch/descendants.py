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

A component process that dies without stopping (SIGKILL, a crash) cannot end what it started: its
orphans are re-parented to the nearest subreaper above it. The fork server is one
(:func:`become_subreaper`), so they become its children: :class:`Orphans` tells them from the
processes the server's own imports started (those are left alone) and ends them (SIGCONT, SIGTERM,
SIGKILL after a grace) without blocking the server. A component process started
as a fresh interpreter (``process_start="spawn"``) is the launcher's own child, and the launcher
(the user's process) is not made a subreaper: there, the orphans of a component killed outright
are left to init.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import time

__all__ = ["Orphans", "become_subreaper", "children", "descendants", "end_descendants", "guard_process"]

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


def become_subreaper() -> bool:
    """Make this process the subreaper of its descendants: their orphans are re-parented to it."""
    return _prctl(_PR_SET_CHILD_SUBREAPER, 1)


def children(pid: int) -> list[int]:
    """The live children of ``pid`` (of all its threads)."""
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
    todo = children(root)
    while todo and len(seen) < 100_000:
        kid = todo.pop(0)
        if kid not in seen and kid != root:
            seen.append(kid)
            todo += children(kid)
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


class Orphans:
    """The children of this (subreaper) process that a component process left behind, ended without blocking.

    This process has three kinds of children: the component processes it forked (the caller's
    ``forked``), those its own code started (a module it imported may start a helper process:
    ``subprocess.Popen`` at import, a ``multiprocessing`` manager), and the orphans re-parented to it
    when a component process died without ending what it had started. Only these are ended. The
    caller reaps its children and then calls :meth:`sort` with the children it has left: a child
    seen for the first time after a pass in which no component process (nor an orphan) was reaped
    is this process's own (its imports', or re-parented from one of those), and is never signalled;
    one that appears with the death of a component process, or of an orphan, is an orphan. Linux re-parents a dying
    process's children before that process can be reaped, under the same lock that
    ``/proc/<pid>/task/*/children`` is read with, so an orphan is never seen before its parent's death is.

    An orphan gets SIGCONT and SIGTERM; :meth:`kill_due` sends SIGKILL to those still there
    ``grace`` seconds later (:meth:`timeout` says when the next one is due; one already SIGKILLed
    waits only to be reaped). The caller calls :meth:`reaped` for each child it reaps, so that a pid
    the system hands out again is never signalled.
    """

    def __init__(self, grace: float = 0.5) -> None:
        self._grace = grace
        self._own: set[int] = set()  # children this process started itself: never ended
        self._ending: dict[int, float] = {}  # orphans sent SIGTERM: when their SIGKILL is due
        self._killed: set[int] = set()  # orphans sent SIGKILL, not reaped yet

    def sort(self, children: set[int], orphaned: bool) -> int:
        """File the children seen for the first time: this process's own, or (``orphaned``: a component
        process or an orphan was reaped since the last call) orphans, which start ending; how many orphans."""
        new = children - self._own - self._ending.keys() - self._killed
        if not orphaned:
            self._own |= new
            return 0
        now = time.monotonic()
        for pid in new:
            _signal(pid, signal.SIGCONT)
            _signal(pid, signal.SIGTERM)
            self._ending[pid] = now + self._grace
        return len(new)

    def reaped(self, pid: int) -> bool:
        """``pid`` (a child of this process) was reaped: never signalled again. Whether it was an orphan."""
        self._own.discard(pid)
        orphan = pid in self._killed or pid in self._ending
        self._ending.pop(pid, None)
        self._killed.discard(pid)
        return orphan

    def timeout(self) -> float | None:
        """Seconds until the next SIGKILL is due; None when none is (those already SIGKILLed wait for nothing)."""
        return max(0.0, min(self._ending.values()) - time.monotonic()) if self._ending else None

    def kill_due(self, now: float | None = None) -> None:
        """SIGKILL the ones whose grace is over (each once; it stays listed until it is reaped)."""
        now = time.monotonic() if now is None else now
        for pid, due in list(self._ending.items()):
            if now >= due:
                _signal(pid, signal.SIGKILL)
                del self._ending[pid]
                self._killed.add(pid)

    def kill_all(self) -> None:
        """SIGKILL every one still being ended (the server is about to exit)."""
        self.kill_due(float("inf"))
