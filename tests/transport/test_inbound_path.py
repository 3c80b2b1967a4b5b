"""The inbound path on every transport (issue 13): one hand-off from the middleware to the worker.

A component's input subscription is inline: the middleware's thread stores the value and
enqueues the step on the component's worker, whose bounded queue is the only queue of the hop.
Checked on each transport with a pair from ``agents_core.testing.pairs`` (values published on
``b``, the component launched on ``a``):

- a burst of 10,000 values into a slow component: exact accounting at the transport (every
  value received was delivered to the input) and at the worker (submitted = executed + dropped
  + discarded), memory bounded by the queue depth, not by the burst;
- a raising inline callback is counted, and the subscription keeps delivering;
- one type per topic is refused on every transport, ROS 2 included;
- a component with three inputs starts at most three threads.
"""

from __future__ import annotations

import contextlib
import threading
import time
import tracemalloc
from collections.abc import Iterator
from typing import Any

import pytest

from agents_core import Launcher, Topic
from agents_core.errors import TransportNotAvailableError, WiringError
from agents_core.ros import QoSConfig
from agents_core.testing.pairs import missing_requirement, pair_factory
from agents_core.transport import Transport
from tests.conftest import wait_for
from tests.recipe_parts import Relay

TRANSPORTS = [pytest.param(name, marks=getattr(pytest.mark, name)) for name in ("memory", "zenoh", "ros2")]


@pytest.fixture(params=TRANSPORTS)
def pair(request: pytest.FixtureRequest) -> Iterator[tuple[Transport, Transport]]:
    name = request.param
    reason = missing_requirement(name)
    if reason is not None:
        pytest.skip(reason)
    try:
        opened = pair_factory(name)()
        transports = opened.__enter__()
    except TransportNotAvailableError as exc:
        pytest.skip(f"{name} transport not available here: {exc}")
    try:
        yield transports
    finally:
        opened.__exit__(None, None, None)


_names = iter(range(1_000_000))


def _unique(stem: str) -> str:
    return f"inbound_{stem}_{next(_names)}_{int(time.time() * 1000) % 100_000}"


def _matched(pub: Any, got: list[Any], probe: Any) -> int:
    """Publish ``probe`` until it arrives (discovery on networked transports); how many were sent."""
    sent = 0

    def once() -> bool:
        nonlocal sent
        pub.publish(probe)
        sent += 1
        return bool(got)

    assert wait_for(once, timeout=15.0, interval=0.1), "the subscription never matched"
    return sent


def _settle(count: Any, quiet: float = 1.0, timeout: float = 60.0) -> None:
    """Wait until ``count()`` has not changed for ``quiet`` seconds (bounded by ``timeout``)."""
    deadline = time.monotonic() + timeout
    last, since = count(), time.monotonic()
    while time.monotonic() < deadline:
        time.sleep(0.05)
        now = count()
        if now != last:
            last, since = now, time.monotonic()
        elif time.monotonic() - since >= quiet:
            return


def test_a_burst_into_a_slow_component_is_accounted_exactly(pair: tuple[Transport, Transport]) -> None:
    a, b = pair
    name = _unique("burst")
    # Deep enough that the middleware itself keeps every sample (DDS history); the component's
    # worker queue (depth 10) is the one that drops.
    words = Topic(name, "String", qos_profile=QoSConfig(depth=10_000))
    relay = Relay(inputs=[words], trigger=words, component_name=_unique("slow"), step_seconds=0.0005)
    relay.config.execution_queue_depth = 10
    launcher = Launcher(transport=a)
    launcher.add_pkg(components=[relay])
    with launcher:
        pub = b.create_publisher(words)
        probes = _matched(pub, relay.seen, "probe")
        tracemalloc.start()
        try:
            for i in range(10_000):
                pub.publish(str(i))
            if a.name == "ros2":
                # DDS may itself drop under a burst (Fast DDS keeps at most 5,000 samples per
                # reader by default), before anything of ours sees them: wait until it settles.
                _settle(lambda: a.statistics(name)[name].delivered)
            else:
                assert wait_for(lambda: a.statistics(name)[name].delivered >= probes + 10_000, timeout=60.0), \
                    a.statistics(name)
            assert wait_for(lambda: relay.worker_statistics().pending == 0, timeout=30.0)
            _, peak = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
        received = a.statistics(name)[name]
        worker = relay.worker_statistics()
    assert b.statistics(name)[name].published == probes + 10_000
    # Transport: every value received went to the component's input, none queued or dropped there.
    if a.name == "ros2":
        assert 0 < received.delivered <= probes + 10_000
    else:
        assert received.delivered == probes + 10_000
    assert (received.dropped, received.callback_errors, received.decode_errors) == (0, 0, 0)
    # Worker: every delivered value became a step that ran, or was dropped by the queue policy.
    assert worker.submitted == received.delivered
    assert worker.executed + worker.dropped + worker.discarded == worker.submitted
    assert worker.dropped > 0, "a slow component must have dropped part of the burst"
    assert len(relay.seen) == worker.executed
    if a.name != "ros2":
        assert relay.seen[-1] == "9999", "drop-oldest keeps the newest value"
    numbers = [int(s) for s in relay.seen if s != "probe"]
    assert numbers == sorted(numbers)
    # Bounded by the queues, not by the burst (10,000 values of ~50 bytes would be ~1 MB of
    # strings alone if they piled up anywhere; with the encoded payloads several MB).
    assert peak < 8 * 1024 * 1024, f"peak traced memory {peak / 1e6:.1f} MB during the burst"


def test_a_raising_inline_callback_is_counted_and_delivery_goes_on(pair: tuple[Transport, Transport]) -> None:
    a, b = pair
    topic = Topic(_unique("raising"), "Int64", qos_profile=QoSConfig(depth=100))
    got: list[int] = []
    threads: set[str] = set()

    def callback(value: int) -> None:
        threads.add(threading.current_thread().name)
        if value == 3:
            raise ValueError("a bad value")
        got.append(value)

    sub = a.create_subscription(topic, callback, inline=True)
    pub = b.create_publisher(topic)
    probes = _matched(pub, got, -1)
    for i in range(6):
        pub.publish(i)
    assert wait_for(lambda: [v for v in got if v >= 0] == [0, 1, 2, 4, 5], timeout=10.0), got
    stats = sub.statistics()
    assert (stats.delivered, stats.callback_errors, stats.queued) == (probes + 5, 1, 0)
    assert not any(t.startswith("deliver:") for t in threads), "inline callbacks need no delivery thread"
    sub.close()


def test_one_type_per_topic_on_every_transport(pair: tuple[Transport, Transport]) -> None:
    a, _ = pair
    name = _unique("typed")
    a.create_publisher(Topic(name, "String"))
    with pytest.raises(WiringError, match=rf"topic '{name}' already carries String; cannot also use it for Int64"):
        a.create_subscription(Topic(name, "Int64"), lambda v: None)
    with pytest.raises(WiringError, match="already carries String"):
        a.create_publisher(Topic(name, "Image"))


def test_a_component_with_three_inputs_starts_at_most_three_threads(pair: tuple[Transport, Transport]) -> None:
    a, _ = pair
    inputs = [Topic(_unique(f"in{i}"), "String") for i in range(3)]
    relay = Relay(inputs=inputs, trigger=inputs, component_name=_unique("three"))
    launcher = Launcher(transport=a)
    launcher.add_pkg(components=[relay])
    before = {t.ident for t in threading.enumerate()}
    with contextlib.ExitStack() as stack:
        stack.enter_context(launcher)
        time.sleep(0.05)
        started = [t.name for t in threading.enumerate() if t.ident not in before]
    # The framework's threads (the middleware's own, e.g. zenoh-python's callback threads, aside);
    # the launcher's action worker belongs to the launcher, not to the component.
    ours = [n for n in started if n.startswith(("worker:", "timer:", "deliver:", "stream:", "memory-request",
                                                "zenoh-request", "ros2-request"))
            and n != "worker:launcher-actions"]
    assert len(ours) <= 3, ours
    if a.name == "memory":
        assert set(started) - {"worker:launcher-actions"} == set(ours), started
