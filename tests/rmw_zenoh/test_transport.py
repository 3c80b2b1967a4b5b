"""The rmw_zenoh transport itself: session configuration as rmw_zenoh's, the router check, custom types,
transient_local, images, and ``agentsctl topics`` on it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import attrs
import numpy as np
import pytest

from agents_core import messages as m
from agents_core.errors import TransportError
from agents_core.supported_types import SupportedType, add_additional_datatypes, get_type, registered_types
from agents_core.testing.helpers import free_tcp_port as free_port
from agents_core.topics import QoSConfig, Topic

from .conftest import rmw_options

pytest.importorskip("rosbags", reason="needs the rmw_zenoh extra")
pytest.importorskip("geometry_msgs", reason="needs the ros2 extra's message packages")

from geometry_msgs.msg import Point

from agents_core import supported_types
from agents_ros2 import conversions
from agents_zenoh.rmw.transport import RmwZenohTransport

pytestmark = pytest.mark.zenoh


def _open(**options: Any) -> Any:
    return RmwZenohTransport(**options)


def _wait(predicate: Any, timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not predicate():
        time.sleep(0.02)
    return bool(predicate())


def test_no_router_is_a_clear_error_within_seconds() -> None:
    start = time.monotonic()
    with pytest.raises(TransportError, match=r"no Zenoh router answered.*agentsctl router"):
        _open(connect=[f"tcp/127.0.0.1:{free_port()}"], listen=["tcp/127.0.0.1:0"], router_timeout=1.0)
    assert time.monotonic() - start < 5


def test_session_configured_from_rmw_zenohs_environment(router: str, tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ROS_DOMAIN_ID", "21")
    monkeypatch.setenv("ZENOH_CONFIG_OVERRIDE", f'connect/endpoints=["{router}"];listen/endpoints=["tcp/127.0.0.1:0"]')
    first = _open()
    config = tmp_path / "session.json5"
    config.write_text(json.dumps({"mode": "peer", "connect": {"endpoints": [router]},
                                  "listen": {"endpoints": ["tcp/127.0.0.1:0"]},
                                  "scouting": {"multicast": {"enabled": False}}}))
    monkeypatch.delenv("ZENOH_CONFIG_OVERRIDE")
    monkeypatch.setenv("ZENOH_SESSION_CONFIG_URI", str(config))
    second = _open()
    try:
        assert first.driver.domain_id == 21
        got: list[str] = []
        second.create_subscription(Topic("env_topic", get_type("String")), got.append)
        pub = first.create_publisher(Topic("env_topic", get_type("String")))
        assert _wait(lambda: pub.publish("x") or bool(got))
        # The publisher's token, in domain 21, as the second session's graph cache (a liveliness subscriber) saw it.
        assert _wait(lambda: any(t.startswith("@ros2_lv/21/") and "/MP/" in t and "%env_topic" in t
                                 for t in second.driver._graph.tokens(0)))
    finally:
        first.close()
        second.close()


@pytest.fixture
def pair(router: str) -> Iterator[tuple[Any, Any]]:
    a, b = _open(**rmw_options(router)), _open(**rmw_options(router))
    try:
        yield a, b
    finally:
        a.close()
        b.close()


def test_late_subscriber_of_a_transient_local_topic_gets_the_last_values(pair: tuple[Any, Any]) -> None:
    a, b = pair
    topic = Topic("latched", get_type("String"), qos_profile=QoSConfig(depth=2, durability="transient_local"))
    pub = a.create_publisher(topic)
    for i in range(3):
        pub.publish(f"v{i}")
    time.sleep(0.3)
    got: list[str] = []
    b.create_subscription(topic, got.append)
    assert _wait(lambda: got == ["v1", "v2"])


def test_image_travels(pair: tuple[Any, Any]) -> None:
    a, b = pair
    got: list[Any] = []
    topic = Topic("camera", get_type("Image"))
    b.create_subscription(topic, got.append)
    frame = np.arange(48 * 64 * 3, dtype=np.uint8).reshape(48, 64, 3)
    pub = a.create_publisher(topic)
    assert _wait(lambda: pub.publish(m.ImageMsg(data=frame, encoding="rgb8")) or bool(got))
    assert np.array_equal(got[0].data, frame)


@attrs.define
class _WheelValue:
    x: float
    y: float
    z: float


class RmwWheelSpeeds(SupportedType):
    """A user's type with a value class of its own, travelling as geometry_msgs/Vector3."""

    value_class = _WheelValue
    _ros_type = "geometry_msgs/msg/Vector3"


class RmwRawPoint(SupportedType):
    """A user's type in the upstream way: the ROS message itself is the value."""

    _ros_type = "geometry_msgs/msg/Point"


@pytest.fixture
def custom_types() -> Iterator[None]:
    add_additional_datatypes([RmwWheelSpeeds, RmwRawPoint])
    yield
    for name in ("RmwWheelSpeeds", "RmwRawPoint"):
        if name in registered_types():
            supported_types._registry.unregister(name)
        conversions._conversions.unregister(name)


def test_custom_ros_types_travel(pair: tuple[Any, Any], custom_types: None) -> None:
    a, b = pair
    wheels: list[Any] = []
    points: list[Any] = []
    b.create_subscription(Topic("wheels", RmwWheelSpeeds), wheels.append)
    b.create_subscription(Topic("raw_point", RmwRawPoint), points.append)
    pw, pp = a.create_publisher(Topic("wheels", RmwWheelSpeeds)), a.create_publisher(Topic("raw_point", RmwRawPoint))
    assert _wait(lambda: pw.publish(_WheelValue(1.0, 2.0, 3.5)) or bool(wheels))
    assert _wait(lambda: pp.publish(Point(x=1.0, y=-2.0, z=0.25)) or bool(points))
    assert wheels[0] == _WheelValue(1.0, 2.0, 3.5)
    assert isinstance(points[0], Point) and (points[0].x, points[0].y, points[0].z) == (1.0, -2.0, 0.25)


def test_agentsctl_topics_list_on_rmw_zenoh(router: str, pair: tuple[Any, Any]) -> None:
    a, _b = pair
    a.create_publisher(Topic("cli_topic", get_type("Float64")))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path), "ROS_DOMAIN_ID": "21"}
    done = subprocess.run([sys.executable, "-m", "agents_core.cli", "topics", "list", "--transport", "rmw_zenoh",
                           "--connect", router, "--json"], capture_output=True, text=True, timeout=120, env=env,
                          check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    listed = json.loads(done.stdout)
    topics = listed["topics"] if isinstance(listed, dict) else listed
    assert {"name": "cli_topic", "msg_type": "Float64", "publishers": 1, "subscribers": 0} in topics


def test_agentsctl_record_on_rmw_zenoh(router: str, pair: tuple[Any, Any], tmp_path: Path) -> None:
    a, _b = pair
    pub = a.create_publisher(Topic("rec_topic", get_type("String")))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path), "ROS_DOMAIN_ID": "21"}
    out = tmp_path / "rec.mcap"
    proc = subprocess.Popen([sys.executable, "-m", "agents_core.cli", "record", str(out), "--transport", "rmw_zenoh",
                             "--connect", router, "--topic", "rec_topic", "--duration", "6", "--no-status"],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while proc.poll() is None and time.monotonic() < deadline:
            pub.publish("recorded")
            time.sleep(0.1)
        stdout, stderr = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, stderr[-2000:]
    from agents_core.recording.reader import read_recording  # noqa: PLC0415  # the record extra

    values = [r.value for r in read_recording(out) if r.topic.lstrip("/") == "rec_topic"]
    assert values and set(values) == {"recorded"}, stdout
