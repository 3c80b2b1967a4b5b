"""agents_core.support.concurrency: the DrainQueue (bounded queue drained by a thread) and CloseOnce.

Unit tests of the queue's ordering, both drop policies, counted drops, the urgent lane, stop
with a stuck handler and a raising handler; then a Hypothesis state machine (derandomized) that
puts, fails, drops, discards and stops in any order while the drain thread runs, and checks the
counting rule at every step: every item offered ends handled, dropped, an error or discarded (or
is still queued or running), in the order it was put.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

import pytest
from hypothesis import settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, precondition, rule

from agents_core.support.concurrency import CloseOnce, DrainQueue, DrainStatistics

WAIT_S = 5.0


def wait_for(predicate: Callable[[], bool], timeout: float = WAIT_S) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.002)


def balance(s: DrainStatistics) -> int:
    """offered minus every outcome: 0 when the counting rule holds."""
    running = s.started - s.handled - s.errors
    assert running in (0, 1), s
    return s.offered - (s.handled + s.errors + s.dropped + s.discarded + s.queued + running)


class Gate:
    """A handler that records items and waits for a permit before each (a slow consumer)."""

    def __init__(self) -> None:
        self.permits = threading.Semaphore(0)
        self.opened = threading.Event()
        self.entered = threading.Semaphore(0)
        self.seen: list[Any] = []

    def __call__(self, item: Any) -> None:
        self.entered.release()
        while not self.permits.acquire(timeout=0.01):
            if self.opened.is_set():
                break
        self.seen.append(item)
        if isinstance(item, str) and item.startswith("fail"):
            raise RuntimeError(f"handler refused {item}")

    def wait_entered(self) -> None:
        assert self.entered.acquire(timeout=WAIT_S), "the handler did not start"

    def open(self) -> None:
        self.opened.set()


class Recording(DrainQueue[Any]):
    """Records what the hooks are told."""

    def __init__(self, handler: Callable[[Any], None], **kwargs: Any) -> None:
        self.hook_handled: list[Any] = []
        self.hook_failed: list[tuple[Any, str]] = []
        self.hook_dropped = 0
        self.hook_discarded = 0
        super().__init__(handler, **kwargs)

    def _handled(self, item: Any) -> None:
        self.hook_handled.append(item)

    def _failed(self, item: Any, error: Exception) -> None:
        self.hook_failed.append((item, str(error)))

    def _dropped(self, count: int) -> None:
        self.hook_dropped += count

    def _discarded(self, count: int) -> None:
        self.hook_discarded += count


def test_items_are_handled_in_order_on_the_named_thread() -> None:
    seen: list[int] = []
    threads: set[str] = set()

    def handler(item: int) -> None:
        threads.add(threading.current_thread().name)
        seen.append(item)

    q: DrainQueue[int] = DrainQueue(handler, depth=1000, name="drain:ordered")
    for i in range(500):
        assert q.put(i)
    wait_for(lambda: q.statistics().handled == 500)
    assert seen == list(range(500))
    assert threads == {"drain:ordered"}
    q.stop()
    assert q.join(WAIT_S)
    assert q.statistics() == DrainStatistics(offered=500, started=500, handled=500)


def test_a_busy_drain_thread_takes_the_next_items_without_being_woken_for_each() -> None:
    # What keeps a component's worker cheap under a stream of values: while the handler runs,
    # puts only append (at most one wake-up token is ever pending), and the thread takes every
    # waiting item in turn before it sleeps again.
    gate = Gate()
    q = Recording(gate, depth=100, name="drain:busy")
    q.put(-1)
    gate.wait_entered()
    for i in range(50):
        assert q.put(i)
    assert q._wake.qsize() <= 1
    gate.open()
    wait_for(lambda: q.statistics().handled == 51)
    assert gate.seen == [-1, *range(50)] and q.hook_handled == gate.seen
    assert q._wake.qsize() <= 1
    # Asleep again, it is woken by the next put.
    wait_for(lambda: not q.statistics().busy)
    assert q.put(50)
    wait_for(lambda: q.statistics().handled == 52)
    q.stop()
    assert q.join(WAIT_S)
    assert q.statistics() == DrainStatistics(offered=52, started=52, handled=52)


@pytest.mark.parametrize("policy", ["drop_oldest", "drop_newest"])
def test_a_full_queue_drops_by_its_policy_and_counts_the_drops(policy: Any) -> None:
    gate = Gate()
    q = Recording(gate, depth=3, policy=policy, name="drain:full")
    assert q.put(0)
    gate.wait_entered()  # 0 runs (blocked): the lane is empty again
    accepted = [q.put(i) for i in range(1, 8)]  # 3 fit, 4 overflow
    s = q.statistics()
    assert (s.offered, s.dropped, s.queued, s.busy) == (8, 4, 3, True)
    assert q.hook_dropped == 4
    assert balance(s) == 0
    gate.open()
    wait_for(lambda: q.statistics().handled == 4)
    if policy == "drop_oldest":
        assert accepted == [True] * 7
        assert gate.seen == [0, 5, 6, 7]
    else:
        assert accepted == [True, True, True, False, False, False, False]
        assert gate.seen == [0, 1, 2, 3]
    assert q.hook_handled == gate.seen
    q.stop()
    assert q.join(WAIT_S)


def test_a_raising_handler_is_counted_and_the_queue_goes_on(caplog: pytest.LogCaptureFixture) -> None:
    seen: list[str] = []

    def handler(item: str) -> None:
        seen.append(item)
        if item.startswith("fail"):
            raise ValueError(item)

    q = Recording(handler, depth=10, name="drain:raising")
    for item in ["a", "fail-1", "b", "fail-2", "c"]:
        q.put(item)
    wait_for(lambda: (q.statistics().handled, q.statistics().errors) == (3, 2))
    assert seen == ["a", "fail-1", "b", "fail-2", "c"]
    assert q.hook_handled == ["a", "b", "c"]
    assert q.hook_failed == [("fail-1", "fail-1"), ("fail-2", "fail-2")]
    q.stop()
    assert q.join(WAIT_S)

    # The default hook logs the error with its traceback, naming the thread.
    plain: DrainQueue[str] = DrainQueue(handler, depth=2, name="drain:logged")
    with caplog.at_level(logging.ERROR, logger="agents_core.support.concurrency"):
        plain.put("fail-3")
        wait_for(lambda: plain.statistics().errors == 1)
        plain.stop()
        assert plain.join(WAIT_S)
    [record] = caplog.records
    assert "drain:logged" in record.getMessage() and record.exc_info is not None


def test_stop_with_a_stuck_handler_returns_and_discards_what_waits() -> None:
    gate = Gate()
    q = Recording(gate, depth=5, name="drain:stuck")
    q.put(1)
    gate.wait_entered()
    for i in range(2, 6):
        q.put(i)
    started = time.monotonic()
    assert q.stop() == 4  # discarded now, counted
    assert not q.join(0.2), "the handler is stuck: join must give up"
    assert time.monotonic() - started < 2.0
    abort = threading.Event()
    abort.set()
    assert not q.join(60.0, abort)  # an abort cuts a long wait short
    assert time.monotonic() - started < 2.0
    assert not q.put(99), "a stopped queue accepts nothing"
    s = q.statistics()
    assert (s.offered, s.discarded, s.queued, s.busy) == (5, 4, 0, True)
    assert q.hook_discarded == 4
    assert balance(s) == 0
    gate.open()
    assert q.join(WAIT_S)
    assert gate.seen == [1]
    assert q.statistics() == DrainStatistics(offered=5, started=1, handled=1, discarded=4)


def test_stop_without_discard_drains_first_and_urgent_items_run_first() -> None:
    gate = Gate()
    q = Recording(gate, depth=10, name="drain:urgent", urgent_limit=2)
    q.put("s0")
    gate.wait_entered()
    q.put("s1")
    q.put("s2")
    assert q.put_urgent("u1") and q.put_urgent("u2")
    assert not q.put_urgent("u3"), "the urgent lane is full"
    s = q.statistics()
    assert (s.queued, s.urgent_queued, s.busy) == (2, 2, True)
    assert q.stop(discard=False) == 0
    assert not q.put_urgent("u4") and q.stopping
    gate.open()
    assert q.join(WAIT_S)
    assert gate.seen == ["s0", "u1", "u2", "s1", "s2"]
    # Urgent items are outside the bounded lane's counts.
    assert q.statistics() == DrainStatistics(offered=3, started=3, handled=3)
    assert q.hook_handled == ["s0", "s1", "s2"]


def test_configure_discard_and_count_discarded() -> None:
    gate = Gate()
    q = Recording(gate, depth=6, name="drain:configure")
    q.put(0)
    gate.wait_entered()
    for i in range(1, 7):
        q.put(i)
    q.configure(depth=2)  # 1..4 go (the oldest), counted as drops
    assert (q.depth, q.statistics().dropped, q.hook_dropped) == (2, 4, 4)
    q.configure(policy="drop_newest")
    assert q.policy == "drop_newest" and not q.put(7)
    assert q.discard() == 2 and q.hook_discarded == 2
    q.count_discarded(3)
    s = q.statistics()
    assert (s.offered, s.dropped, s.discarded, s.queued) == (11, 5, 5, 0)
    assert balance(s) == 0
    with pytest.raises(ValueError, match="depth"):
        q.configure(depth=0)
    with pytest.raises(ValueError, match="policy"):
        q.configure(policy="drop_all")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="depth"):
        DrainQueue(gate, depth=0, name="drain:never")
    gate.open()
    q.stop()
    assert q.join(WAIT_S)
    assert gate.seen == [0]


def test_wait_item_done_and_join_from_the_drain_thread() -> None:
    gate = Gate()
    q: DrainQueue[Any] = DrainQueue(gate, depth=2, name="drain:wait")
    assert q.wait_item_done(0.01)
    q.put(1)
    gate.wait_entered()
    assert q.running
    assert not q.wait_item_done(0.05)
    gate.permits.release()
    assert q.wait_item_done(WAIT_S)
    assert not q.running

    inside: list[bool] = []

    def stops_itself(item: Any) -> None:
        inside.append(own.on_drain_thread)
        own.stop()
        inside.append(own.join(WAIT_S))

    own: DrainQueue[Any] = DrainQueue(stops_itself, depth=1, name="drain:self")
    own.put(1)
    assert own.join(WAIT_S)
    assert inside == [True, False] and not own.on_drain_thread
    gate.open()
    q.stop()
    assert q.join(WAIT_S)


def test_close_once_lets_one_caller_close() -> None:
    once = CloseOnce()
    assert not once.closed
    winners: list[bool] = []
    barrier = threading.Barrier(8)

    def close() -> None:
        barrier.wait()
        winners.append(once.claim())

    threads = [threading.Thread(target=close) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(WAIT_S)
    assert sorted(winners) == [False] * 7 + [True]
    assert once.closed and not once.claim()
    assert "closed=True" in repr(once)


# -- the counting rule, under any sequence of operations (Hypothesis) -------------------------------


class CountingRule(RuleBasedStateMachine):
    """Any mix of puts (some raising), permits, policy changes, discards and a stop: each item
    offered ends in exactly one outcome, and the handled ones in the order they were put."""

    @initialize(depth=st.integers(1, 4), policy=st.sampled_from(["drop_oldest", "drop_newest"]))
    def start(self, depth: int, policy: Any) -> None:
        self.gate = Gate()
        self.queue = Recording(self.gate, depth=depth, policy=policy, name="drain:counting")
        self.next_id = 0
        self.put_ids: list[str] = []
        self.stopped = False

    @rule(fails=st.booleans())
    def put(self, fails: bool) -> None:
        item = f"{'fail' if fails else 'ok'}-{self.next_id}"
        self.next_id += 1
        self.queue.put(item)
        if not self.stopped:  # offered: queued, or dropped at once by drop_newest
            self.put_ids.append(item)

    @rule(count=st.integers(1, 3))
    def release(self, count: int) -> None:
        for _ in range(count):
            self.gate.permits.release()

    @rule(depth=st.integers(1, 4), policy=st.sampled_from(["drop_oldest", "drop_newest"]))
    def configure(self, depth: int, policy: Any) -> None:
        self.queue.configure(depth, policy)

    @rule()
    def discard(self) -> None:
        self.queue.discard()

    @rule(count=st.integers(1, 2))
    def count_discarded(self, count: int) -> None:
        self.queue.count_discarded(count)
        self.put_ids.extend(f"counted-{self.next_id + i}" for i in range(count))
        self.next_id += count

    @precondition(lambda self: not self.stopped)
    @rule(discard=st.booleans())
    def stop(self, discard: bool) -> None:
        self.queue.stop(discard=discard)
        self.stopped = True

    @invariant()
    def counts_balance(self) -> None:
        s = self.queue.statistics()
        assert balance(s) == 0
        assert s.offered == len(self.put_ids)
        assert (s.dropped, s.discarded) == (self.queue.hook_dropped, self.queue.hook_discarded)

    def teardown(self) -> None:
        self.gate.open()
        self.queue.stop(discard=False)
        assert self.queue.join(WAIT_S)
        s = self.queue.statistics()
        assert (s.queued, s.urgent_queued, s.busy, s.started) == (0, 0, False, s.handled + s.errors)
        assert s.handled + s.errors + s.dropped + s.discarded == s.offered == len(self.put_ids)
        # Handled in the order put (drops and discards only leave gaps).
        order = {item: i for i, item in enumerate(self.put_ids)}
        positions = [order[item] for item in self.gate.seen]
        assert positions == sorted(positions)
        assert self.queue.hook_handled == [i for i in self.gate.seen if i.startswith("ok")]
        assert [i for i, _ in self.queue.hook_failed] == [i for i in self.gate.seen if i.startswith("fail")]
        assert (s.handled, s.errors) == (len(self.queue.hook_handled), len(self.queue.hook_failed))


CountingRule.TestCase.settings = settings(max_examples=60, stateful_step_count=25, deadline=None,
                                          derandomize=True, database=None)
test_every_item_ends_in_one_outcome = CountingRule.TestCase
