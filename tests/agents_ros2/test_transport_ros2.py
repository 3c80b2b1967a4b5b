"""ROS 2 transport behaviour beyond the conformance suite: slow handlers, status, profiles."""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip("rclpy", reason="needs the ros2 extra")
pytest.importorskip("agents_interfaces", reason="needs agents_interfaces (pip install --no-build-isolation "
                                                "./interfaces)")

from agents_core.errors import ConfigError, RequestTimeoutError, ServiceUnavailableError
from agents_core.messages import ComponentStatusMsg
from agents_core.status import HealthStatus, LifecycleState
from agents_core.topics import QoSConfig, Topic
from agents_ros2 import qos
from agents_ros2.transport import Ros2Transport
from tests.conformance.ros2_pair import private_ros_environment, ros2_pair
from tests.conftest import wait_for

pytestmark = pytest.mark.ros2

#: Names carry the PID: two test runs that happen to share a ROS domain must not cross-talk.
SUFFIX = f"_{os.getpid()}"


@pytest.fixture
def pair() -> Iterator[tuple[Ros2Transport, Ros2Transport]]:
    with ros2_pair() as transports:
        yield transports


def test_a_slow_handler_does_not_stall_messages_or_other_services(
        pair: tuple[Ros2Transport, Ros2Transport]) -> None:
    a, b = pair
    release = threading.Event()
    a.create_service("slow_op" + SUFFIX, lambda req: {"waited": release.wait(5.0)})
    a.create_service("fast_op" + SUFFIX, lambda req: {"echo": req["x"]})
    topic = Topic("ticks_while_busy" + SUFFIX, "Int64", qos_profile=QoSConfig(depth=100))
    received: list[int] = []
    a.create_subscription(topic, received.append)
    pub = b.create_publisher(topic)
    assert wait_for(lambda: (pub.publish(-1), bool(received))[1], timeout=10.0, interval=0.1)
    assert b.request("fast_op" + SUFFIX, {"x": 0}, timeout=10.0) == {"echo": 0}

    slow_result: list[Any] = []
    caller = threading.Thread(
        target=lambda: slow_result.append(b.request("slow_op" + SUFFIX, {}, timeout=10.0)))
    caller.start()
    try:
        time.sleep(0.3)  # the slow handler now blocks in a's service pool
        start = len(received)
        for i in range(20):
            pub.publish(i)
        assert wait_for(lambda: len(received) - start >= 20, timeout=5.0), "messages stalled behind a handler"
        assert b.request("fast_op" + SUFFIX, {"x": 7}, timeout=3.0) == {"echo": 7}
    finally:
        release.set()
        caller.join(timeout=10.0)
    assert slow_result == [{"waited": True}]


def test_request_timeout_leaves_the_client_usable(pair: tuple[Ros2Transport, Ros2Transport]) -> None:
    a, b = pair
    def sometimes_slow(req: dict[str, Any]) -> dict[str, Any]:
        if req.get("sleep"):
            time.sleep(1.0)
        return {"v": req.get("v")}

    a.create_service("sometimes_slow" + SUFFIX, sometimes_slow)
    assert b.request("sometimes_slow" + SUFFIX, {"v": 1}, timeout=10.0) == {"v": 1}
    with pytest.raises(RequestTimeoutError):
        b.request("sometimes_slow" + SUFFIX, {"sleep": True}, timeout=0.2)
    assert b.request("sometimes_slow" + SUFFIX, {"v": 2}, timeout=5.0) == {"v": 2}


def test_a_components_own_status_publisher_shares_the_status_stream(
        pair: tuple[Ros2Transport, Ros2Transport]) -> None:
    a, b = pair
    presence = a.declare_component("camera_driver" + SUFFIX, on_transition=lambda t: True)
    presence.update(LifecycleState.ACTIVE, HealthStatus.HEALTHY)
    status_topic = Topic(f"camera_driver{SUFFIX}/status", "ComponentStatus")
    own = a.create_publisher(status_topic, owner="camera_driver" + SUFFIX)
    own.publish(ComponentStatusMsg(component="camera_driver" + SUFFIX, lifecycle_state="active",
                                   health="SYSTEM_FAILURE", message="usb unplugged"))
    presence.update(LifecycleState.ACTIVE, HealthStatus.SYSTEM_FAILURE, "usb unplugged")

    def seen() -> bool:
        state = b.get_component_state("camera_driver" + SUFFIX, timeout=1.0)
        return state is not None and state.health == "SYSTEM_FAILURE" and state.lifecycle_state == "active"

    assert wait_for(seen, timeout=10.0, interval=0.1)
    # One writer on the status topic: the presence's, shared with the component's publisher.
    assert a.driver.node.count_publishers(f"/camera_driver{SUFFIX}/status") == 1
    own.close()
    presence.close()


def test_unknown_component_is_none_and_cannot_be_driven(pair: tuple[Ros2Transport, Ros2Transport]) -> None:
    _, b = pair
    assert b.get_component_state("nobody_here" + SUFFIX, timeout=0.3) is None
    with pytest.raises(ServiceUnavailableError, match="nobody_here" + SUFFIX):
        b.request_transition("nobody_here" + SUFFIX, "activate", timeout=0.3)


def test_options_are_checked() -> None:
    with pytest.raises(ConfigError, match="executor"):
        Ros2Transport(executor="multi")  # type: ignore[arg-type]


def test_shared_memory_profile_is_opt_out(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(qos.FASTDDS_PROFILE_ENV_VAR, raising=False)
    monkeypatch.setenv(qos.SHM_ENV_VAR, "0")
    assert qos.shared_memory_wanted(None) is False
    assert qos.shared_memory_wanted(True) is True
    monkeypatch.delenv(qos.SHM_ENV_VAR)
    assert qos.shared_memory_wanted(None) is True
    assert qos.enable_shared_memory_profile() is True
    assert os.environ[qos.FASTDDS_PROFILE_ENV_VAR].endswith("fastdds_shm.xml")
    monkeypatch.setenv(qos.FASTDDS_PROFILE_ENV_VAR, "/etc/my_profile.xml")
    assert qos.enable_shared_memory_profile() is False


def test_events_executor_option_works() -> None:
    domain_id = private_ros_environment()
    a = Ros2Transport(domain_id=domain_id, executor="events")
    b = Ros2Transport(domain_id=domain_id, executor="events")
    try:
        a.create_service("events_echo" + SUFFIX, lambda req: {"echo": req["x"]})
        topic = Topic("events_topic" + SUFFIX, "String")
        received: list[str] = []
        a.create_subscription(topic, received.append)
        pub = b.create_publisher(topic)
        assert wait_for(lambda: (pub.publish("hi"), bool(received))[1], timeout=10.0, interval=0.1)
        assert b.request("events_echo" + SUFFIX, {"x": 3}, timeout=10.0) == {"echo": 3}
    finally:
        b.close()
        a.close()
