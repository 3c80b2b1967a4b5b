"""The transport conformance suite: the same promises checked on every installed transport.

Collected by the :mod:`agents_core.testing` pytest plugin (never import it into a test module of
your own: the plugin already collects it once). Every test takes ``transport_pair``: ``a``
publishes / serves / declares, ``b`` subscribes / requests / observes; on memory (and on a
third-party transport without a pair factory) both are the same object.
"""

from __future__ import annotations

import itertools
import threading
import time
from typing import Any

import numpy as np
import pytest

from agents_core.errors import (
    RemoteError,
    RequestTimeoutError,
    ServiceUnavailableError,
    TransportClosedError,
    TypeValidationError,
)
from agents_core.status import HealthStatus, LifecycleState
from agents_core.topics import QoSConfig, Topic
from agents_core.transport import Transport
from agents_core.types.base import registered_types
from agents_core.types.fields import values_equal

from .goals_suite import (  # noqa: F401 - collected as part of this suite
    test_goal_a_raising_execute_aborts_with_its_message,
    test_goal_bad_goal_fields_are_refused_before_sending,
    test_goal_cancel_mid_goal_and_cancel_of_a_finished_goal,
    test_goal_inline_feedback_refuses_waiting_calls_and_cancels_without_waiting,
    test_goal_rejected_by_accept_and_nobody_serving,
    test_goal_round_trip_with_feedback,
    test_goal_server_closed_mid_goal_aborts_the_client,
    test_goal_several_goals_run_at_once,
    test_goal_unsupported_transport_says_so,
)
from .helpers import wait_for

_ids = itertools.count()


def unique(name: str) -> str:
    """Topic names unique per test, so parallel or repeated runs never cross-talk."""
    return f"conf_{name}_{next(_ids)}_{int(time.time() * 1000) % 100000}"


def _wait_matched(pub: Any, b: Transport, topic: Topic, received: list[Any], probe: Any) -> int:
    """Publish ``probe`` until the subscription sees something (discovery on networked transports).

    Returns how many probes were published.
    """
    sent = 0

    def probe_once() -> bool:
        nonlocal sent
        pub.publish(probe)
        sent += 1
        return bool(received)

    assert wait_for(probe_once, timeout=10.0, interval=0.1), f"subscription on {topic.name} never matched"
    return sent


@pytest.mark.parametrize("type_name", sorted(registered_types()))
def test_every_registered_type_round_trips(transport_pair: tuple[Transport, Transport], type_name: str) -> None:
    a, b = transport_pair
    msg_type = registered_types()[type_name]
    topic = Topic(unique(type_name), msg_type)
    received: list[Any] = []
    sub = b.create_subscription(topic, received.append)
    pub = a.create_publisher(topic)
    value = msg_type.example()
    _wait_matched(pub, b, topic, received, value)
    for got in received:
        assert values_equal(got, msg_type.validate(value)), f"{type_name}: sent {value!r}, got {got!r}"
    sub.close()
    pub.close()


def test_header_stamp_and_frame_survive(transport_pair: tuple[Transport, Transport]) -> None:
    a, b = transport_pair
    topic = Topic(unique("image"), "Image")
    received: list[Any] = []
    sub = b.create_subscription(topic, received.append)
    pub = a.create_publisher(topic)
    _wait_matched(pub, b, topic, received, topic.msg_type.example())
    got = received[-1]
    assert got.header.stamp_ns == 1_700_000_000_123_456_789
    assert got.header.frame_id == "camera"
    sub.close()


def test_large_image_round_trips(transport_pair: tuple[Transport, Transport]) -> None:
    a, b = transport_pair
    topic = Topic(unique("big_image"), "Image")
    received: list[Any] = []
    sub = b.create_subscription(topic, received.append)
    pub = a.create_publisher(topic)
    pixels = np.random.default_rng(0).integers(0, 255, (480, 640, 3), dtype=np.uint8)
    _wait_matched(pub, b, topic, received, pixels)
    assert np.array_equal(received[-1].data, pixels)
    sub.close()


def test_values_arrive_in_order(transport_pair: tuple[Transport, Transport]) -> None:
    a, b = transport_pair
    topic = Topic(unique("ordered"), "Int64", qos_profile=QoSConfig(depth=1000))
    received: list[int] = []
    sub = b.create_subscription(topic, received.append)
    pub = a.create_publisher(topic)
    _wait_matched(pub, b, topic, received, -1)
    start = len(received)
    for i in range(200):
        pub.publish(i)
    assert wait_for(lambda: len([v for v in received[start:] if v >= 0]) == 200, timeout=10.0)
    assert [v for v in received[start:] if v >= 0] == list(range(200))
    sub.close()


def test_slow_subscriber_keeps_at_most_depth_and_counts_drops(transport_pair: tuple[Transport, Transport]) -> None:
    a, b = transport_pair
    depth = 3
    topic = Topic(unique("slow"), "Int64", qos_profile=QoSConfig(depth=depth))
    gate = threading.Event()
    received: list[int] = []

    def slow(value: int) -> None:
        received.append(value)
        gate.wait(10.0)

    sub = b.create_subscription(topic, slow)
    pub = a.create_publisher(topic)
    probes = _wait_matched(pub, b, topic, received, -1)  # the callback now blocks on the first value
    total = 50
    for i in range(total):
        pub.publish(i)
    # Wait until every value is either queued or dropped, then release the callback. The probes
    # after the first (which is blocked inside the callback) are queued or dropped as well, so they
    # count towards the same total: leaving them out would release the gate one value early.
    def all_accounted() -> bool:
        stats = sub.statistics()
        return stats.dropped + stats.queued >= (probes - 1) + total

    assert wait_for(all_accounted, timeout=10.0)
    assert sub.statistics().queued <= depth
    gate.set()
    assert wait_for(lambda: sub.statistics().queued == 0, timeout=10.0)
    stats = sub.statistics()
    later = [v for v in received if v >= 0]
    assert len(later) <= depth
    assert later == list(range(total))[-len(later):], "the newest values must be the ones kept"
    # Nothing is lost silently: every value sent was either delivered or counted as dropped.
    assert stats.delivered + stats.dropped == probes + total
    assert len(received) == stats.delivered
    sub.close()


def test_per_topic_statistics_account_for_every_value(transport_pair: tuple[Transport, Transport]) -> None:
    a, b = transport_pair
    topic = Topic(unique("stats"), "Int64", qos_profile=QoSConfig(depth=100))
    received: list[int] = []

    def receive(value: int) -> None:
        if value == 3:
            raise ValueError("counted as a callback error")
        received.append(value)

    sub = b.create_subscription(topic, receive)
    pub = a.create_publisher(topic)
    probes = _wait_matched(pub, b, topic, received, -1)
    for i in range(10):
        pub.publish(i)
    assert wait_for(lambda: len(received) == probes + 9, timeout=10.0)
    sent = a.statistics()[topic.name]
    got = b.statistics(topic.name)[topic.name]
    assert sent.published >= probes + 10
    assert got.callback_errors == 1
    assert got.delivered == len(received)
    # On networked transports the publisher's side counts what it sent, the subscriber's what it received.
    assert got.delivered + got.dropped + got.callback_errors == probes + 10
    assert set(b.statistics(topic.name)) == {topic.name}
    sub.close()


def test_callback_error_does_not_kill_subscription(transport_pair: tuple[Transport, Transport]) -> None:
    a, b = transport_pair
    topic = Topic(unique("raising"), "String")
    good: list[str] = []

    def picky(value: str) -> None:
        if value == "bad":
            raise ValueError("cannot handle this one")
        good.append(value)

    sub = b.create_subscription(topic, picky)
    pub = a.create_publisher(topic)
    _wait_matched(pub, b, topic, good, "probe")
    pub.publish("bad")
    pub.publish("after")
    assert wait_for(lambda: "after" in good)
    assert wait_for(lambda: sub.statistics().callback_errors >= 1)
    sub.close()


def test_publish_rejects_a_value_of_the_wrong_type(transport_pair: tuple[Transport, Transport]) -> None:
    a, _ = transport_pair
    pub = a.create_publisher(Topic(unique("typed"), "Image"))
    with pytest.raises(TypeValidationError, match="Image"):
        pub.publish("not an image")
    with pytest.raises(TypeValidationError):
        pub.publish(np.zeros((4, 4, 3), dtype=np.float32))
    pub.close()


def test_request_reply(transport_pair: tuple[Transport, Transport]) -> None:
    a, b = transport_pair
    name = unique("srv")
    server = a.create_service(name, lambda req: {"sum": req["x"] + req["y"], "echo": req})
    reply = _request_when_ready(b, name, {"x": 2, "y": 40, "nested": {"list": [1, "two", None]}})
    assert reply["sum"] == 42
    assert reply["echo"]["nested"] == {"list": [1, "two", None]}
    server.close()


def _request_when_ready(b: Transport, name: str, payload: dict[str, Any]) -> dict[str, Any]:
    deadline = time.monotonic() + 10.0
    while True:
        try:
            return b.request(name, payload, timeout=2.0)
        except (ServiceUnavailableError, RequestTimeoutError):
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)


def test_request_times_out_cleanly(transport_pair: tuple[Transport, Transport]) -> None:
    a, b = transport_pair
    name = unique("slow_srv")
    release = threading.Event()

    def slow(req: dict[str, Any]) -> dict[str, Any]:
        if req.get("probe"):
            return {"ok": True}
        release.wait(5.0)
        return {"late": True}

    server = a.create_service(name, slow)
    _request_when_ready(b, name, {"probe": True})
    start = time.monotonic()
    with pytest.raises(RequestTimeoutError):
        b.request(name, {}, timeout=0.3)
    assert time.monotonic() - start < 3.0
    release.set()
    server.close()


def test_remote_error_carries_the_message(transport_pair: tuple[Transport, Transport]) -> None:
    a, b = transport_pair
    name = unique("failing_srv")

    def failing(req: dict[str, Any]) -> dict[str, Any]:
        if req.get("probe"):
            return {}
        raise ValueError("the gripper is closed")

    server = a.create_service(name, failing)
    _request_when_ready(b, name, {"probe": True})
    with pytest.raises(RemoteError, match="the gripper is closed"):
        b.request(name, {}, timeout=5.0)
    server.close()


def test_request_to_missing_service_fails(transport_pair: tuple[Transport, Transport]) -> None:
    _, b = transport_pair
    with pytest.raises((ServiceUnavailableError, RequestTimeoutError)):
        b.request(unique("nobody"), {}, timeout=0.5)


def test_component_presence_is_visible_and_drivable(transport_pair: tuple[Transport, Transport]) -> None:
    a, b = transport_pair
    name = unique("comp")
    asked: list[str] = []

    def on_transition(transition: str) -> bool:
        asked.append(transition)
        return transition == "deactivate"

    presence = a.declare_component(name, on_transition=on_transition)
    presence.update(LifecycleState.ACTIVE, HealthStatus.ALGORITHM_FAILURE, "no detections")

    def seen() -> bool:
        state = b.get_component_state(name, timeout=1.0)
        return state is not None and state.lifecycle_state == "active" and state.health == "ALGORITHM_FAILURE"

    assert wait_for(seen, timeout=10.0, interval=0.1)
    assert b.request_transition(name, "deactivate", timeout=5.0) is True
    assert b.request_transition(name, "activate", timeout=5.0) is False
    assert asked == ["deactivate", "activate"]
    presence.close()
    assert wait_for(lambda: b.get_component_state(name, timeout=0.5) is None, timeout=10.0, interval=0.1)


def test_closed_transport_refuses_work(transport_pair: tuple[Transport, Transport]) -> None:
    a, _ = transport_pair
    topic = Topic(unique("after_close"), "String")
    pub = a.create_publisher(topic)
    pub.close()
    with pytest.raises(TransportClosedError):
        pub.publish("late")
