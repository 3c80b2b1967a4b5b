"""The core's two small concurrency primitives: a bounded queue drained by a thread of its own,
and a guard that lets a ``close()`` run once.

:class:`DrainQueue` is what a subscription's delivery
(:class:`~agents_core.transport.delivery.BoundedDelivery`), a sent goal's feedback and a
component's step worker (:class:`~agents_core.components.worker.StepWorker`) are built on:

- a *bounded lane* of ``depth`` items; when it is full, the ``policy`` decides which item goes
  (``drop_oldest``: the one waiting longest; ``drop_newest``: the one being put), and the drop is
  counted; ``put`` never blocks, so a slow handler cannot stall the producer's thread;
- an optional *urgent lane* (``urgent_limit`` items), never dropped, whose items run before the
  bounded lane's (a component's actions and service calls);
- one daemon thread that calls ``handler(item)`` for each item in order; a handler that raises
  is logged and counted, and the thread goes on;
- :meth:`~DrainQueue.stop` (waiting items discarded and counted, or left to be handled first)
  and :meth:`~DrainQueue.join` with a timeout, so a stuck handler cannot hang a shutdown.

The counting rule of the bounded lane: every item offered ends handled, dropped, errors
(its handler raised) or discarded, or is still queued or running::

    offered == handled + errors + dropped + discarded + queued + (started - handled - errors)

where ``started - handled - errors`` is 1 while a bounded-lane item runs, else 0. Urgent items are
outside this rule (their producer gets their outcome another way). Subclasses that keep counters
of their own (a topic's totals, say) override the hooks :meth:`~DrainQueue._handled`,
:meth:`~DrainQueue._failed`, :meth:`~DrainQueue._dropped` and :meth:`~DrainQueue._discarded`.

:class:`CloseOnce` answers "is this the first close?" once, thread-safely, for the objects whose
``close()`` must be idempotent.
"""

from __future__ import annotations

import collections
import logging
import queue
import threading
import time
from collections.abc import Callable
from typing import Generic, Literal, TypeVar

from attrs import define

__all__ = ["CloseOnce", "DrainQueue", "DrainStatistics", "DropPolicy", "wait_on_thread"]

logger = logging.getLogger(__name__)

T = TypeVar("T")

#: Which item a full bounded lane gives up: the one waiting longest, or the one being put.
DropPolicy = Literal["drop_oldest", "drop_newest"]
_POLICIES = ("drop_oldest", "drop_newest")

# What runs on the drain thread now (see DrainQueue._running).
_IDLE, _BOUNDED, _URGENT = 0, 1, 2


def wait_on_thread(thread: threading.Thread, timeout: float, abort: threading.Event | None = None) -> bool:
    """Join ``thread`` for up to ``timeout`` s, sooner when ``abort`` is set; True if it ended."""
    if abort is None:
        thread.join(max(0.0, timeout))
        return not thread.is_alive()
    deadline = time.monotonic() + timeout
    while thread.is_alive():
        remaining = deadline - time.monotonic()
        if remaining <= 0 or abort.is_set():
            return False
        # Short joins, so that a set ``abort`` is seen within 50 ms.
        thread.join(min(remaining, 0.05))
    return True


@define
class DrainStatistics:
    """A snapshot of a :class:`DrainQueue`'s counters (see the module docstring for their rule)."""

    #: Items put into the bounded lane while it was open, those dropped at once included.
    offered: int = 0
    #: Bounded-lane items whose handler has started.
    started: int = 0
    #: Bounded-lane items whose handler returned.
    handled: int = 0
    #: Bounded-lane items whose handler raised.
    errors: int = 0
    #: Items the full lane gave up (by its policy, or a smaller depth).
    dropped: int = 0
    #: Items forgotten unhandled (:meth:`DrainQueue.discard`, a discarding stop, or counted by
    #: :meth:`DrainQueue.count_discarded`).
    discarded: int = 0
    #: Items waiting in the bounded lane.
    queued: int = 0
    #: Items waiting in the urgent lane.
    urgent_queued: int = 0
    #: Whether an item (of either lane) runs now.
    busy: bool = False


class DrainQueue(Generic[T]):
    """A bounded queue drained by a thread of its own into ``handler`` (see the module docstring).

    :param handler: called with each item, one at a time, on the drain thread.
    :param depth: how many items the bounded lane holds (at least 1).
    :param policy: which item a full bounded lane drops.
    :param name: the drain thread's name (logs and tests see it).
    :param urgent_limit: how many items the urgent lane holds (0: no urgent lane).

    The thread starts at once; it is a daemon, so a handler stuck for good cannot keep the
    process alive.
    """

    def __init__(self, handler: Callable[[T], None], *, depth: int, policy: DropPolicy = "drop_oldest",
                 name: str, urgent_limit: int = 0) -> None:
        _check_limits(depth, policy)
        self._handler = handler
        self._depth = depth
        self._policy: DropPolicy = policy
        self._urgent_limit = urgent_limit
        self._items: collections.deque[T] = collections.deque()
        self._urgent: collections.deque[T] = collections.deque()
        self._lock = threading.Lock()
        # Signalled when an item ends, only while someone waits for it (wait_item_done).
        self._item_done = threading.Condition(self._lock)
        self._done_waiters = 0
        # The drain thread sleeps in SimpleQueue.get, whose wake-up is C code, cheaper than a
        # Condition's. It says so in ``_sleeping`` (under the lock) before it sleeps, and only
        # the producer that finds it sleeping puts a token: at most one token is ever pending,
        # and a thread that is busy takes the next waiting item without sleeping or being woken
        # (one lock round per item, no token per item). A token whose item was dropped or
        # discarded meanwhile wakes the thread for nothing, which is harmless.
        self._wake: queue.SimpleQueue[None] = queue.SimpleQueue()
        self._sleeping = False
        self._stats = DrainStatistics()
        self._stopping = False
        self._running = _IDLE
        self._thread = threading.Thread(target=self._drain, name=name, daemon=True)
        self._thread.start()

    # -- producers ---------------------------------------------------------------------------------

    def put(self, item: T) -> bool:
        """Queue ``item`` in the bounded lane; never blocks.

        False when this item is not queued: the queue is stopped (the item is not counted), or
        the lane is full under ``drop_newest`` (counted as dropped). Under ``drop_oldest`` a full
        lane drops the item waiting longest instead (counted) and this one is queued.
        """
        with self._lock:
            if self._stopping:
                return False
            self._stats.offered += 1
            items = self._items
            full = len(items) >= self._depth
            if full:
                self._stats.dropped += 1
                if self._policy == "drop_newest":
                    queued = False
                else:
                    items.popleft()
                    items.append(item)
                    queued = True
                wake = False  # the lane was not empty, so the thread is awake or woken already
            else:
                items.append(item)
                queued = True
                # Inline (no method call): this runs for every item (see __init__).
                wake = self._sleeping
                self._sleeping = False
        if wake:
            self._wake.put(None)
        if full:
            self._dropped(1)
        return queued

    def put_urgent(self, item: T) -> bool:
        """Queue ``item`` ahead of the bounded lane's items; never dropped, never blocks.

        False when it is not queued: the queue is stopped, or ``urgent_limit`` items already wait
        (:attr:`stopping` tells which).
        """
        with self._lock:
            if self._stopping or len(self._urgent) >= self._urgent_limit:
                return False
            self._urgent.append(item)
            wake = self._sleeping
            self._sleeping = False
        if wake:
            self._wake.put(None)
        return True

    def count_discarded(self, count: int = 1) -> None:
        """Count ``count`` items as offered and discarded without queueing them.

        For a producer that decides to drop items before they reach the queue (a component that
        is not active), so that the counting rule still covers every item it received.
        """
        with self._lock:
            self._stats.offered += count
            self._stats.discarded += count
        self._discarded(count)

    # -- settings and control ----------------------------------------------------------------------

    @property
    def depth(self) -> int:
        """How many items the bounded lane holds."""
        return self._depth

    @property
    def policy(self) -> DropPolicy:
        """Which item a full bounded lane drops."""
        return self._policy

    def configure(self, depth: int | None = None, policy: DropPolicy | None = None) -> None:
        """Change the depth or the policy while running; a smaller depth drops the oldest waiting
        items beyond it (counted)."""
        _check_limits(self._depth if depth is None else depth, self._policy if policy is None else policy)
        with self._lock:
            if policy is not None:
                self._policy = policy
            dropped = 0
            if depth is not None:
                self._depth = depth
                while len(self._items) > depth:
                    self._items.popleft()
                    dropped += 1
                self._stats.dropped += dropped
        if dropped:
            self._dropped(dropped)

    def discard(self) -> int:
        """Forget the bounded lane's waiting items (counted); returns how many."""
        with self._lock:
            count = len(self._items)
            self._items.clear()
            self._stats.discarded += count
        if count:
            self._discarded(count)
        return count

    @property
    def stopping(self) -> bool:
        """Whether :meth:`stop` ran (nothing more is accepted)."""
        return self._stopping

    def stop(self, *, discard: bool = True) -> int:
        """Accept nothing more and let the drain thread end; returns how many items were discarded.

        The thread first handles the urgent lane's waiting items and, with ``discard=False``,
        the bounded lane's too; with ``discard=True`` those are discarded now (counted). The item
        running is never interrupted. Does not wait: see :meth:`join`. Calling it again is harmless.
        """
        with self._lock:
            self._stopping = True
            count = 0
            if discard:
                count = len(self._items)
                self._items.clear()
                self._stats.discarded += count
            wake = self._sleeping  # a thread that is awake sees _stopping before it sleeps again
            self._sleeping = False
        if wake:
            self._wake.put(None)
        if count:
            self._discarded(count)
        return count

    def join(self, timeout: float, abort: threading.Event | None = None) -> bool:
        """Wait for the drain thread to end, up to ``timeout`` s, sooner when ``abort`` is set.

        True if it ended; False at once when called from the drain thread itself (a handler that
        stops its own queue).
        """
        if self.on_drain_thread:
            return False
        return wait_on_thread(self._thread, timeout, abort)

    # -- state -------------------------------------------------------------------------------------

    @property
    def on_drain_thread(self) -> bool:
        """True when called from the drain thread (from within a handler)."""
        return threading.current_thread() is self._thread

    @property
    def running(self) -> bool:
        """True while a bounded-lane item (not an urgent one) runs."""
        with self._lock:
            return self._running == _BOUNDED

    def wait_item_done(self, timeout: float, abort: threading.Event | None = None) -> bool:
        """Wait until no bounded-lane item runs (waiting ones are not waited for); True if so in time.

        Gives up after ``timeout`` s, or soon after ``abort`` is set.
        """
        deadline = time.monotonic() + timeout
        with self._item_done:
            self._done_waiters += 1
            try:
                while self._running == _BOUNDED:
                    remaining = deadline - time.monotonic()
                    if remaining <= 0 or (abort is not None and abort.is_set()):
                        return False
                    # Short waits, so that a set ``abort`` is seen within 50 ms.
                    self._item_done.wait(min(remaining, 0.05))
            finally:
                self._done_waiters -= 1
        return True

    def statistics(self) -> DrainStatistics:
        """A snapshot of the counters."""
        with self._lock:
            s = self._stats
            return DrainStatistics(s.offered, s.started, s.handled, s.errors, s.dropped, s.discarded,
                                   len(self._items), len(self._urgent), self._running != _IDLE)

    # -- hooks for subclasses (called on the thread that caused the event, outside the lock) -------

    def _handled(self, item: T) -> None:
        """A bounded-lane item's handler returned (on the drain thread)."""

    def _failed(self, item: T, error: Exception) -> None:
        """An item's handler raised ``error`` (on the drain thread, inside the ``except`` block, so
        ``logger.exception`` shows the traceback); the default logs it."""
        logger.exception("the handler of %r raised; the queue goes on", self._thread.name)

    def _dropped(self, count: int) -> None:
        """``count`` items were dropped by the policy or a smaller depth (on the producer's thread)."""

    def _discarded(self, count: int) -> None:
        """``count`` items were discarded (on the thread that discarded, stopped or counted them)."""

    # -- the drain thread --------------------------------------------------------------------------

    def _drain(self) -> None:
        get, lock, stats, items, urgent = self._wake.get, self._lock, self._stats, self._items, self._urgent
        handler = self._handler
        # The no-op default hook is not called at all: this runs for every item.
        on_handled = None if type(self)._handled is DrainQueue._handled else self._handled
        lane = _IDLE  # the lane of the item just handled (_IDLE: none)
        failed = False
        item: T | None = None
        while True:
            with lock:
                # One lock round per item: the end of the previous item and the start of the
                # next one (a busy queue drains without sleeping; see __init__).
                if lane != _IDLE:
                    self._running = _IDLE
                    if lane == _BOUNDED:
                        if failed:
                            stats.errors += 1
                        else:
                            stats.handled += 1
                    if self._done_waiters:
                        self._item_done.notify_all()
                done, done_lane, done_failed = item, lane, failed
                if urgent:
                    item = urgent.popleft()
                    lane = _URGENT
                elif items:
                    item = items.popleft()
                    lane = _BOUNDED
                    # Counted as it starts: what runs after the handler is kept minimal, since the
                    # thread it handed a value to may be waiting for the GIL meanwhile.
                    stats.started += 1
                elif self._stopping:
                    lane = _IDLE
                else:
                    lane = _IDLE
                    self._sleeping = True
                self._running = lane
            if on_handled is not None and done_lane == _BOUNDED and not done_failed:
                on_handled(done)  # type: ignore[arg-type]  # a bounded-lane item, never None
            if lane == _IDLE:
                if self._stopping:
                    return
                get()
                continue
            failed = False
            try:
                handler(item)  # type: ignore[arg-type]  # set with lane, never None here
            except Exception as exc:
                failed = True
                self._failed(item, exc)  # type: ignore[arg-type]


def _check_limits(depth: int, policy: str) -> None:
    if depth < 1:
        raise ValueError(f"a queue's depth must be at least 1, got {depth}")
    if policy not in _POLICIES:
        raise ValueError(f"a queue's policy must be one of {_POLICIES}, got {policy!r}")


class CloseOnce:
    """Lets the first of any number of ``close()`` calls, from any threads, do the closing.

    ``if not self._close_once.claim(): return`` replaces the hand-written
    ``with lock: if self._closed: return; self._closed = True``.
    """

    __slots__ = ("_lock", "closed")

    def __init__(self) -> None:
        self._lock = threading.Lock()
        #: Whether :meth:`claim` has run; read it without the lock (it only ever goes from False
        #: to True), never assign it. A plain attribute, not a property: hot paths (``publish``)
        #: check it on every call.
        self.closed = False

    def claim(self) -> bool:
        """Mark closed; True for the first call only."""
        with self._lock:
            if self.closed:
                return False
            self.closed = True
            return True

    def __repr__(self) -> str:
        return f"<CloseOnce closed={self.closed}>"
