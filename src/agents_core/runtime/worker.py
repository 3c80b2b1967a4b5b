"""A component's serial worker and its periodic timer.

Each component runs everything it does (steps, actions, fallbacks) on one thread of its own, so
two steps of a component never overlap and a slow model never blocks a transport thread.

The worker has two lanes: *steps* (bounded by ``execution_queue_depth``; when full, the policy
``drop_oldest`` or ``drop_newest`` decides which step is discarded, and the drop is counted) and
*control* items (actions, fallbacks, service calls), which are never dropped and run before
pending steps.
"""

from __future__ import annotations

import contextvars
import logging
import math
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future
from typing import Any

from attrs import define

from ..errors import ComponentError
from ..support.concurrency import DrainQueue, DropPolicy

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


@define
class WorkerStatistics:
    """Counters of a component's worker."""

    submitted: int = 0
    executed: int = 0
    dropped: int = 0
    discarded: int = 0
    #: queued items plus the one running now
    pending: int = 0


def _call(item: Callable[[], None]) -> None:
    item()


class _WorkerQueue(DrainQueue[Callable[[], None]]):
    """A worker's items: steps in the bounded lane, control items in the urgent one."""

    def __init__(self, name: str, depth: int, policy: DropPolicy) -> None:
        self._owner = name
        super().__init__(_call, depth=depth, policy=policy, name=f"worker:{name}", urgent_limit=MAX_PENDING_CONTROL)

    def _failed(self, item: Callable[[], None], error: Exception) -> None:
        logger.exception("unhandled error on the worker of %r", self._owner)


class StepWorker:
    """Runs submitted callables one at a time on a dedicated thread (``worker:<name>``).

    Built on a :class:`~agents_core.support.concurrency.DrainQueue`: steps are its bounded lane, control
    items its urgent lane.
    """

    def __init__(self, name: str, depth: int, policy: DropPolicy) -> None:
        self.name = name
        self._queue = _WorkerQueue(name, depth, policy)

    @property
    def depth(self) -> int:
        """How many pending steps the worker keeps."""
        return self._queue.depth

    @property
    def policy(self) -> DropPolicy:
        """Which step a full queue drops."""
        return self._queue.policy

    @property
    def on_worker_thread(self) -> bool:
        """True when called from this worker's own thread."""
        return self._queue.on_drain_thread

    def submit_step(self, step: Callable[[], None]) -> bool:
        """Queue a step; returns False if the queue policy dropped this one."""
        return self._queue.put(step)

    def set_queue(self, depth: int | None = None, policy: DropPolicy | None = None) -> None:
        """Change the step queue's depth or full policy while running (a smaller depth drops the
        oldest pending steps beyond it, counted)."""
        self._queue.configure(depth, policy)

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

        if not self._queue.put_urgent(run):
            if self._queue.stopping:
                raise ComponentError(f"component {self.name!r} is shut down")
            raise ComponentError(f"component {self.name!r} has {MAX_PENDING_CONTROL} pending actions")
        return future

    def count_discarded(self) -> None:
        """Count a step that was discarded before it reached the queue (its component was not active)."""
        self._queue.count_discarded()

    def discard_steps(self) -> int:
        """Forget the pending steps (on deactivate); returns how many were discarded."""
        return self._queue.discard()

    @property
    def running_step(self) -> bool:
        """True while a step (not a control item) runs."""
        return self._queue.running

    def wait_step_done(self, timeout: float, abort: threading.Event | None = None) -> bool:
        """Wait until no step is running (pending ones are not waited for); True if so in time."""
        return self._queue.wait_item_done(timeout, abort)

    def statistics(self) -> WorkerStatistics:
        """A snapshot of the counters."""
        s = self._queue.statistics()
        return WorkerStatistics(s.offered, s.started, s.dropped, s.discarded,
                                s.queued + s.urgent_queued + int(s.busy))

    def stop(self, timeout: float = 10.0, abort: threading.Event | None = None) -> bool:
        """Finish the item in progress and the pending control items, then end the thread.

        Waits up to ``timeout`` s, less when ``abort`` is set meanwhile (a second Ctrl-C); an item
        still running then is left to finish on its (daemon) thread. True if the thread ended.
        """
        self._queue.stop(discard=True)
        if self.on_worker_thread:
            return False
        if self._queue.join(timeout, abort):
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
