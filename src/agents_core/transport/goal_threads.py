"""Threads that goals borrow: one goal (or one goal's feedback) at a time, kept a while for the next.

Starting a thread costs a few hundred microseconds under load, which a goal of a few milliseconds
feels. :class:`ReusedThreads` hands a job to a thread that is idle (a wake-up of a
``SimpleQueue``, C code) and starts one only when none is; a thread with no job for ``idle_s``
seconds ends, so an idle process does not keep them. Each job runs alone on its thread, under
the name it is given (logs and tests read it), so a goal still has a thread of its own for as
long as it runs.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Callable

__all__ = ["IDLE_S", "ReusedThreads"]

logger = logging.getLogger(__name__)

#: How long a thread with no job waits for the next before it ends.
IDLE_S = 2.0

Job = Callable[[], None]


class _Worker:
    """One thread and its mailbox (a job, or None: end)."""

    def __init__(self) -> None:
        self.mailbox: queue.SimpleQueue[tuple[Job, str] | None] = queue.SimpleQueue()
        self.thread: threading.Thread | None = None
        # A job to run on this thread as soon as the current one returns (see ReusedThreads.then).
        self.then: tuple[Job, str] | None = None


class ReusedThreads:
    """Runs each job on a thread of its own for the job's duration, reusing idle threads (module docstring).

    :param name: the name of a thread between jobs.
    :param idle_s: how long an idle thread waits for a job before it ends.
    """

    def __init__(self, name: str, *, idle_s: float = IDLE_S) -> None:
        self._name = name
        self._idle_s = idle_s
        self._lock = threading.Lock()
        self._idle: list[_Worker] = []
        self._busy = 0
        self._closed = False
        self._local = threading.local()

    def run(self, job: Job, name: str) -> threading.Thread:
        """Run ``job`` on an idle thread (renamed ``name`` while it runs) or a new one; returns that thread.

        Raises RuntimeError once :meth:`close` ran.
        """
        with self._lock:
            if self._closed:
                raise RuntimeError(f"threads {self._name!r} are closed")
            self._busy += 1
            if self._idle:
                worker = self._idle.pop()
                # Put under the lock: a worker whose wait just ran out finds it (see _loop).
                worker.mailbox.put((job, name))
                assert worker.thread is not None
                return worker.thread
        worker = _Worker()
        worker.mailbox.put((job, name))
        worker.thread = threading.Thread(target=self._loop, args=(worker,), name=name, daemon=True)
        try:
            worker.thread.start()
        except BaseException:
            with self._lock:
                self._busy -= 1
            raise
        return worker.thread

    def then(self, job: Job, name: str) -> threading.Thread | None:
        """Run ``job`` on the calling thread right after its current job returns (no hand-off).

        Returns the thread, or None when the caller is not one of these threads (nothing is queued then).
        """
        worker: _Worker | None = getattr(self._local, "worker", None)
        if worker is None or worker.then is not None:
            return None
        worker.then = (job, name)
        return worker.thread

    @property
    def busy(self) -> int:
        """How many threads run a job now."""
        return self._busy

    def _loop(self, worker: _Worker) -> None:
        me = threading.current_thread()
        self._local.worker = worker
        item = worker.mailbox.get()
        while item is not None:
            try:
                while item is not None:
                    job, name = item
                    me.name = name
                    try:
                        job()
                    except Exception:  # a job's own error must not take the thread (and its count) down
                        logger.exception("a job on thread %r raised", name)
                    item, worker.then = worker.then, None
            finally:
                me.name = self._name
                with self._lock:
                    self._busy -= 1
                    closed = self._closed
                    if not closed:
                        self._idle.append(worker)
            if closed:
                return
            try:
                item = worker.mailbox.get(timeout=self._idle_s)
            except queue.Empty:
                with self._lock:
                    if worker in self._idle:  # nobody picked it meanwhile: end
                        self._idle.remove(worker)
                        return
                # Picked between the timeout and the lock: its job is in the mailbox already.
                item = worker.mailbox.get_nowait()

    def idle_count(self) -> int:
        """How many threads wait for a job now."""
        with self._lock:
            return len(self._idle)

    def close(self) -> None:
        """Start no more jobs; idle threads end now, busy ones when their job returns. Idempotent."""
        with self._lock:
            self._closed = True
            idle, self._idle = self._idle, []
        for worker in idle:
            worker.mailbox.put(None)
