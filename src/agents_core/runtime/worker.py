"""A component's serial worker and its periodic timer.

Each component runs everything it does (steps, actions, fallbacks) on one thread of its own, so
two steps of a component never overlap and a slow model never blocks a transport thread.

The worker has two lanes: *steps* (bounded by ``execution_queue_depth``; when full, the policy
``drop_oldest`` or ``drop_newest`` decides which step is discarded, and the drop is counted) and
*control* items (actions, fallbacks, service calls), which are never dropped and run before
pending steps.
"""

from __future__ import annotations

import collections
import contextvars
import logging
import math
import queue
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future
from typing import Any, Literal

from attrs import define

from ..errors import ComponentError

__all__ = ["MAX_TIMER_RATE_HZ", "PeriodicTimer", "StepWorker", "WorkerStatistics", "control_deadline_passed"]

logger = logging.getLogger(__name__)

#: Control items beyond this many pending mean something is flooding a component with actions.
MAX_PENDING_CONTROL = 10_000
#: The fastest timer a component may ask for: a Python thread cannot keep a shorter period.
MAX_TIMER_RATE_HZ = 1000.0

# The monotonic time by which the caller of the running control item stops waiting (None: never).
_control_deadline: contextvars.ContextVar[float | None] = contextvars.ContextVar("control_deadline", default=None)


def control_deadline_passed() -> bool:
    """True when the caller of the control item running now has already given up waiting.

    A long action (switching model clients, say) checks it before committing its effect, so an
    action whose caller timed out does not take effect anyway.
    """
    deadline = _control_deadline.get()
    return deadline is not None and time.monotonic() >= deadline


def wait_on_thread(thread: threading.Thread, timeout: float, abort: threading.Event | None) -> bool:
    """Join ``thread`` for up to ``timeout`` s, sooner when ``abort`` is set; True if it ended."""
    deadline = time.monotonic() + timeout
    while thread.is_alive():
        remaining = deadline - time.monotonic()
        if remaining <= 0 or (abort is not None and abort.is_set()):
            return False
        thread.join(min(remaining, 0.05))
    return True


@define
class WorkerStatistics:
    """Counters of a component's worker."""

    submitted: int = 0
    executed: int = 0
    dropped: int = 0
    discarded: int = 0
    #: queued items plus the one running now
    pending: int = 0


class StepWorker:
    """Runs submitted callables one at a time on a dedicated thread."""

    def __init__(self, name: str, depth: int, policy: Literal["drop_oldest", "drop_newest"]) -> None:
        self.name = name
        self.depth = depth
        self.policy = policy
        self._steps: collections.deque[Callable[[], None]] = collections.deque()
        self._control: collections.deque[Callable[[], None]] = collections.deque()
        self._lock = threading.Lock()
        # Signalled when an item ends (wait_step_done waits on it).
        self._cond = threading.Condition(self._lock)
        # One token per queued item (and one to stop): the thread sleeps in SimpleQueue.get, whose
        # wake-up is C code, cheaper than a Condition's. A token whose item was dropped meanwhile
        # wakes the thread for nothing, which is harmless.
        self._wake: queue.SimpleQueue[bool] = queue.SimpleQueue()
        self._stats = WorkerStatistics()
        self._stopping = False
        self._busy = False
        self._busy_is_step = False
        self._done_waiters = 0
        self._thread = threading.Thread(target=self._run, name=f"worker:{name}", daemon=True)
        self._thread.start()

    @property
    def on_worker_thread(self) -> bool:
        """True when called from this worker's own thread."""
        return threading.current_thread() is self._thread

    def submit_step(self, step: Callable[[], None]) -> bool:
        """Queue a step; returns False if the queue policy dropped this one."""
        with self._cond:
            if self._stopping:
                return False
            self._stats.submitted += 1
            if len(self._steps) >= self.depth:
                self._stats.dropped += 1
                if self.policy == "drop_newest":
                    return False
                self._steps.popleft()
            self._steps.append(step)
        self._wake.put(True)
        return True

    def set_queue(self, depth: int | None = None,
                  policy: Literal["drop_oldest", "drop_newest"] | None = None) -> None:
        """Change the step queue's depth or full policy while running (a smaller depth drops the
        oldest pending steps beyond it, counted)."""
        with self._cond:
            if policy is not None:
                self.policy = policy
            if depth is not None:
                self.depth = depth
                while len(self._steps) > depth:
                    self._steps.popleft()
                    self._stats.dropped += 1

    def submit_control(self, func: Callable[[], Any], deadline: float | None = None) -> Future[Any]:
        """Queue a control item ahead of pending steps; its result arrives in the returned future.

        ``deadline`` (monotonic seconds) is when the caller stops waiting: an item not started by
        then is skipped, and one running can ask :func:`control_deadline_passed`.
        """
        future: Future[Any] = Future()

        def run() -> None:
            if not future.set_running_or_notify_cancel():
                return
            if deadline is not None and time.monotonic() >= deadline:
                future.set_exception(TimeoutError("the caller stopped waiting before the item started"))
                return
            token = _control_deadline.set(deadline)
            try:
                future.set_result(func())
            except BaseException as exc:
                future.set_exception(exc)
            finally:
                _control_deadline.reset(token)

        with self._cond:
            if self._stopping:
                raise ComponentError(f"component {self.name!r} is shut down")
            if len(self._control) >= MAX_PENDING_CONTROL:
                raise ComponentError(f"component {self.name!r} has {MAX_PENDING_CONTROL} pending actions")
            self._control.append(run)
        self._wake.put(True)
        return future

    def count_discarded(self) -> None:
        """Count a step that was discarded before it reached the queue (its component was not active)."""
        with self._cond:
            self._stats.submitted += 1
            self._stats.discarded += 1

    def discard_steps(self) -> int:
        """Forget the pending steps (on deactivate); returns how many were discarded."""
        with self._cond:
            n = len(self._steps)
            self._steps.clear()
            self._stats.discarded += n
            return n

    @property
    def running_step(self) -> bool:
        """True while a step (not a control item) runs."""
        with self._cond:
            return self._busy and self._busy_is_step

    def wait_step_done(self, timeout: float, abort: threading.Event | None = None) -> bool:
        """Wait until no step is running (pending ones are not waited for); True if so in time."""
        deadline = time.monotonic() + timeout
        with self._cond:
            self._done_waiters += 1
            try:
                while self._busy and self._busy_is_step:
                    remaining = deadline - time.monotonic()
                    if remaining <= 0 or (abort is not None and abort.is_set()):
                        return False
                    self._cond.wait(min(remaining, 0.05))
            finally:
                self._done_waiters -= 1
        return True

    def statistics(self) -> WorkerStatistics:
        """A snapshot of the counters."""
        with self._cond:
            s = self._stats
            return WorkerStatistics(s.submitted, s.executed, s.dropped, s.discarded,
                                    len(self._steps) + len(self._control) + int(self._busy))

    def _run(self) -> None:
        while True:
            self._wake.get()
            with self._lock:
                if self._control:
                    item = self._control.popleft()
                    is_step = False
                elif self._steps:
                    item = self._steps.popleft()
                    is_step = True
                    # Counted as it starts (pending counts it until it ends): what runs after
                    # the item is kept minimal, since the thread it handed a value to may be
                    # waiting for the GIL meanwhile.
                    self._stats.executed += 1
                elif self._stopping:
                    return
                else:
                    continue  # the token of an item dropped or discarded meanwhile
                self._busy = True
                self._busy_is_step = is_step
            try:
                item()
            except Exception:
                logger.exception("unhandled error on the worker of %r", self.name)
            with self._lock:
                self._busy = False
                self._busy_is_step = False
                if self._done_waiters:
                    self._cond.notify_all()

    def stop(self, timeout: float = 10.0, abort: threading.Event | None = None) -> bool:
        """Finish the item in progress and the pending control items, then end the thread.

        Waits up to ``timeout`` s, less when ``abort`` is set meanwhile (a second Ctrl-C); an item
        still running then is left to finish on its (daemon) thread. True if the thread ended.
        """
        with self._cond:
            self._stopping = True
            self._stats.discarded += len(self._steps)
            self._steps.clear()
        self._wake.put(False)
        if self.on_worker_thread:
            return False
        if wait_on_thread(self._thread, timeout, abort):
            return True
        logger.warning("worker of %r is still busy; not waiting for it any longer", self.name)
        return False


class PeriodicTimer:
    """Calls ``func`` at ``rate`` Hz on its own thread until stopped (drift-free schedule)."""

    def __init__(self, rate: float, func: Callable[[], None], name: str) -> None:
        if not math.isfinite(rate) or not 0 < rate <= MAX_TIMER_RATE_HZ:
            raise ComponentError(f"timer {name!r}: rate must be a finite number in (0, {MAX_TIMER_RATE_HZ:g}] Hz, "
                                 f"got {rate}")
        self.period = 1.0 / rate
        self._func = func
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"timer:{name}", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        next_time = time.monotonic() + self.period
        while not self._stop.wait(max(0.0, next_time - time.monotonic())):
            try:
                self._func()
            except Exception:
                logger.exception("timer %r callback raised", self._thread.name)
            next_time += self.period
            now = time.monotonic()
            if next_time < now:  # fell behind (slow callback): skip missed ticks, keep the phase
                next_time += ((now - next_time) // self.period + 1) * self.period

    def stop(self) -> None:
        """Stop ticking; returns once the thread has ended (unless called from the callback)."""
        self._stop.set()
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout=5.0)
