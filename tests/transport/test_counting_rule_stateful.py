"""The counting rule as a Hypothesis state machine, on the memory transport and on two Zenoh peers.

Every value a subscription receives ends in exactly one of delivered, dropped, callback_errors or
discarded (or is still queued): see ``Transport.statistics`` in agents_core.transport.contract.
The machine opens subscriptions (slow or fast callbacks, some raising, on a queue of depth 3 so
bursts drop), publishes bursts, and closes subscriptions with values still queued (discarded);
after each step every open subscription has counted each value published since it was matched.

On Zenoh a new subscription is matched first (probe values until one arrives, then wait until
nothing more is in flight): what was published before the match never reached it.
"""

from __future__ import annotations

import contextlib
import itertools
import time
from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import Any

import pytest
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, precondition, rule

from agents_core.ros import QoSConfig
from agents_core.testing.helpers import wait_for
from agents_core.testing.pairs import memory_pair, skip_unless_installed, zenoh_pair
from agents_core.topics import Topic
from agents_core.transport.contract import Transport

_NAMES = itertools.count()
#: Values divisible by this make a callback raise (counted in callback_errors).
RAISE_ON = 7


class _Watched:
    """One subscription and what the machine expects it to have counted."""

    def __init__(self, transport: Transport, topic: Topic, slow: bool) -> None:
        self.ok = 0
        self.raised = 0
        self.base_total = 0
        self.base_published = 0
        self.slow = slow
        self.sub = transport.create_subscription(topic, self._on_value)

    def _on_value(self, value: int) -> None:
        if self.slow:
            time.sleep(0.003)  # slower than a burst is published: the queue of 3 overflows
        if value % RAISE_ON == 0:
            self.raised += 1
            raise ValueError(f"refused {value}")
        self.ok += 1

    def total(self) -> int:
        """Every value this subscription has counted, the queued ones included."""
        s = self.sub.statistics()
        return s.delivered + s.dropped + s.callback_errors + s.discarded + s.queued

    def expected(self, published: int) -> int:
        return self.base_total + published - self.base_published


def _machine(open_pair: Callable[[], AbstractContextManager[tuple[Transport, Transport]]],
             settle_s: float, quiet_s: float) -> type[RuleBasedStateMachine]:
    """A state machine class over the transports ``open_pair`` yields.

    ``settle_s``: how long values may travel; ``quiet_s``: how long nothing arrives once all have.
    """

    class CountingRule(RuleBasedStateMachine):
        def __init__(self) -> None:
            super().__init__()
            self._stack = contextlib.ExitStack()
            self.a, self.b = self._stack.enter_context(open_pair())
            self.topic = Topic(f"counting/t{next(_NAMES)}", "Int64", qos_profile=QoSConfig(depth=3))
            self.pub = self.a.create_publisher(self.topic)
            self._stack.callback(self.pub.close)
            self.published = 0
            self.open: list[_Watched] = []

        def _publish(self, value: int) -> None:
            self.pub.publish(value)
            self.published += 1

        def _settled(self, watched: _Watched) -> bool:
            return wait_for(lambda: watched.total() >= watched.expected(self.published), timeout=settle_s)

        @precondition(lambda self: len(self.open) < 3)
        @rule(slow=st.booleans())
        def open_subscription(self, slow: bool) -> None:
            watched = _Watched(self.b, self.topic, slow)
            # Matched once a probe arrived (1 never raises); then wait until nothing more is in flight.
            deadline = time.monotonic() + 10 * settle_s
            while watched.total() == 0 and time.monotonic() < deadline:
                self._publish(1)
                wait_for(lambda: watched.total() > 0, timeout=min(0.2, settle_s))
            assert watched.total() > 0, "the new subscription was never matched"
            last = -1
            while watched.total() != last:
                last = watched.total()
                time.sleep(quiet_s)
            watched.base_total, watched.base_published = watched.total(), self.published
            self.open.append(watched)

        @rule(values=st.lists(st.integers(min_value=0, max_value=100), min_size=1, max_size=12))
        def publish_burst(self, values: list[int]) -> None:
            for value in values:
                self._publish(value)

        @precondition(lambda self: bool(self.open))
        @rule(index=st.integers(min_value=0, max_value=2))
        def close_subscription(self, index: int) -> None:
            watched = self.open.pop(index % len(self.open))
            assert self._settled(watched)
            expected = watched.expected(self.published)
            watched.sub.close()  # what is still queued is discarded now
            s = watched.sub.statistics()
            assert s.queued == 0
            assert s.delivered + s.dropped + s.callback_errors + s.discarded == expected, s
            assert (s.delivered, s.callback_errors) == (watched.ok, watched.raised), s

        @invariant()
        def every_received_value_is_counted_once(self) -> None:
            for watched in self.open:
                self._settled(watched)
                assert watched.total() == watched.expected(self.published), watched.sub.statistics()

        @invariant()
        def the_publisher_counts_what_it_sent(self) -> None:
            assert self.a.statistics(self.topic.name)[self.topic.name].published == self.published

        def teardown(self) -> None:
            for watched in self.open:
                watched.sub.close()
            self._stack.close()

    return CountingRule


def _run(open_pair: Callable[[], Any], settle_s: float, quiet_s: float, examples: int, steps: int) -> None:
    machine = _machine(open_pair, settle_s, quiet_s)
    machine.TestCase.settings = settings(max_examples=examples, stateful_step_count=steps, deadline=None,
                                         suppress_health_check=[HealthCheck.too_slow])
    machine.TestCase().runTest()


@pytest.mark.memory
def test_counting_rule_on_memory() -> None:
    _run(memory_pair, settle_s=2.0, quiet_s=0.01, examples=40, steps=15)


@pytest.mark.zenoh
def test_counting_rule_on_zenoh() -> None:
    skip_unless_installed("zenoh")
    _run(zenoh_pair, settle_s=3.0, quiet_s=0.2, examples=15, steps=10)
