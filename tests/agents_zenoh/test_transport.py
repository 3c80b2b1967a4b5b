"""What the Zenoh transport does beyond the shared conformance suite: wire details, QoS, config.

Everything runs in this process on loopback (explicit ``tcp/127.0.0.1`` ports, multicast
scouting off); "raw" is a plain Zenoh session standing in for a third-party client.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

pytest.importorskip("zenoh")
pytest.importorskip("msgpack")

import msgpack
import zenoh

from agents_core.errors import (
    ConfigError,
    RemoteError,
    ServiceUnavailableError,
    TopicNameError,
    TransportClosedError,
)
from agents_core.status import HealthStatus, LifecycleState
from agents_core.supported_types import SupportedType
from agents_core.topics import QoSConfig, Topic
from agents_core.transport import resolve_transport
from agents_zenoh import ZenohConfig
from agents_zenoh import session as session_module
from agents_zenoh.codecs import CodecError
from agents_zenoh.transport import ZenohTransport
from tests.conformance.zenoh_pair import free_tcp_port
from tests.conftest import wait_for

pytestmark = pytest.mark.zenoh

_FAST = {"scouting/delay": 50}


def _raw_session(connect_port: int) -> Any:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", "[]")
    conf.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{connect_port}"]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("scouting/delay", "50")
    return zenoh.open(conf)


@pytest.fixture
def trio() -> Iterator[tuple[ZenohTransport, ZenohTransport, Any]]:
    """Transport ``a`` listening, transport ``b`` and a raw Zenoh session connected to it."""
    port = free_tcp_port()
    a = ZenohTransport(listen=[f"tcp/127.0.0.1:{port}"], connect=[], zenoh_options=_FAST)
    b = ZenohTransport(listen=[], connect=[f"tcp/127.0.0.1:{port}"], zenoh_options=_FAST)
    raw = _raw_session(port)
    try:
        yield a, b, raw
    finally:
        raw.close()
        b.close()
        a.close()


def _unique(name: str) -> str:
    return f"zt_{name}_{time.monotonic_ns() % 10**9}"


def test_first_value_is_not_lost_to_discovery(trio: tuple[ZenohTransport, ZenohTransport, Any]) -> None:
    a, b, _ = trio
    for i in range(5):
        topic = Topic(_unique(f"first{i}"), "Int64")
        got: list[int] = []
        sub = b.create_subscription(topic, got.append)
        pub = a.create_publisher(topic)
        pub.publish(i)  # at once: the publisher waits (bounded) for the subscriber to be matched
        assert wait_for(lambda got=got, i=i: got == [i], timeout=5.0), got
        sub.close()
        pub.close()


def test_samples_carry_encoding_schema_and_attachment(trio: tuple[ZenohTransport, ZenohTransport, Any]) -> None:
    a, _, raw = trio
    topic = Topic(_unique("attach"), "String")
    samples: list[Any] = []
    sub = raw.declare_subscriber(a.key_expr(topic), lambda s: samples.append(
        (str(s.encoding), msgpack.unpackb(s.payload.to_bytes()), msgpack.unpackb(s.attachment.to_bytes()))))
    pub = a.create_publisher(topic)
    before = time.time_ns()
    for text in ("a", "b", "c"):
        pub.publish(text)
    assert wait_for(lambda: len(samples) == 3)
    assert [s[0] for s in samples] == ["application/msgpack;String"] * 3
    assert [s[1] for s in samples] == ["a", "b", "c"]
    assert [s[2]["seq"] for s in samples] == [0, 1, 2]
    assert all(before <= s[2]["stamp_ns"] <= time.time_ns() for s in samples)
    sub.undeclare()


def test_undecodable_samples_are_counted_logged_once_and_skipped(
    trio: tuple[ZenohTransport, ZenohTransport, Any], caplog: pytest.LogCaptureFixture
) -> None:
    a, _, raw = trio
    topic = Topic(_unique("bad"), "Int64")
    got: list[int] = []
    sub = a.create_subscription(topic, got.append)
    key = a.key_expr(topic)
    pub = raw.declare_publisher(key, encoding="application/msgpack;Int64")
    assert wait_for(lambda: pub.matching_status.matching)
    with caplog.at_level(logging.WARNING, logger="agents_zenoh.transport"):
        pub.put(b"\xc1")  # corrupt
        pub.put(msgpack.packb("seven"))  # wrong value for the type
        raw.put(key, msgpack.packb(7), encoding="application/msgpack;String")  # wrong type schema
        raw.put(key, msgpack.packb(7), encoding="text/plain")  # not msgpack
        pub.put(msgpack.packb(8))
        assert wait_for(lambda: got == [8] and sub.statistics().decode_errors == 4), (got, sub.statistics())
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING and topic.name in r.getMessage()]
    assert len(warnings) == 1
    assert "cannot decode the sample as Int64" in warnings[0].getMessage()
    stats = sub.statistics()
    assert (stats.delivered, stats.callback_errors) == (1, 0)
    sub.close()
    pub.undeclare()


def test_per_topic_statistics_are_public(trio: tuple[ZenohTransport, ZenohTransport, Any]) -> None:
    a, b, raw = trio
    topic = Topic(_unique("counted"), "Int64", qos_profile=QoSConfig(depth=100))
    got: list[int] = []

    def receive(value: int) -> None:
        if value == 3:
            raise ValueError("a raising callback is counted, not fatal")
        got.append(value)

    a.create_subscription(topic, receive)
    pub = b.create_publisher(topic)
    for i in range(5):
        pub.publish(i)
    # The raw session may not have seen a's subscriber yet (a put nobody is known to want is not
    # sent): put again, a bounded number of times, until one payload that does not decode is counted.
    puts = 0
    while puts < 20 and a.statistics(topic.name)[topic.name].decode_errors == 0:
        raw.put(a.key_expr(topic), b"\xc1", encoding="application/msgpack;Int64")
        puts += 1
        wait_for(lambda: a.statistics(topic.name)[topic.name].decode_errors > 0, timeout=0.5)
    assert wait_for(lambda: a.statistics(topic.name)[topic.name].decode_errors >= 1 and len(got) == 4), (
        got, a.statistics())
    sent = b.statistics()[topic.name]
    received = a.statistics()[topic.name]
    assert sent.published == 5
    assert (received.delivered, received.callback_errors, received.dropped) == (4, 1, 0)
    assert 1 <= received.decode_errors <= puts
    assert received.published == 0
    assert set(a.statistics(topic.name)) == {topic.name}


def test_transient_local_replays_the_last_depth_values(trio: tuple[ZenohTransport, ZenohTransport, Any]) -> None:
    a, b, _ = trio
    topic = Topic(_unique("latched"), "Int64", qos_profile=QoSConfig(depth=3, durability="transient_local"))
    pub = a.create_publisher(topic)
    for i in range(5):
        pub.publish(i)
    late: list[int] = []
    sub = b.create_subscription(topic, late.append)
    assert wait_for(lambda: late == [2, 3, 4], timeout=5.0), late
    pub.publish(5)
    assert wait_for(lambda: late == [2, 3, 4, 5]), late
    volatile: list[int] = []
    plain = b.create_subscription(Topic(topic.name, "Int64"), volatile.append)
    time.sleep(0.3)
    assert volatile == []  # a volatile subscriber gets no history
    sub.close()
    plain.close()
    pub.close()


def test_qos_maps_to_zenoh_reliability_congestion_and_priority() -> None:
    port = free_tcp_port()
    with ZenohTransport(listen=[f"tcp/127.0.0.1:{port}"], priorities={"cmd_vel": "real_time"}) as t:
        reliable = t.create_publisher(Topic("cmd_vel", "Twist"))
        lossy = t.create_publisher(Topic("camera", "Image", qos_profile=QoSConfig(reliability="best_effort")))
        assert reliable._sender._pub.congestion_control == zenoh.CongestionControl.BLOCK
        assert reliable._sender._pub.priority == zenoh.Priority.REAL_TIME
        assert lossy._sender._pub.congestion_control == zenoh.CongestionControl.DROP
        assert lossy._sender._pub.priority == zenoh.Priority.DATA
        got: list[Any] = []
        sub = t.create_subscription(lossy.topic, got.append)
        lossy.publish(np.zeros((2, 2, 3), np.uint8))
        assert wait_for(lambda: len(got) == 1)
        sub.close()


def test_namespaces_separate_graphs() -> None:
    port = free_tcp_port()
    a = ZenohTransport(listen=[f"tcp/127.0.0.1:{port}"], namespace="/robot1/", zenoh_options=_FAST)
    same = ZenohTransport(connect=[f"tcp/127.0.0.1:{port}"], listen=[], namespace="robot1", zenoh_options=_FAST)
    other = ZenohTransport(connect=[f"tcp/127.0.0.1:{port}"], listen=[], namespace="robot2", zenoh_options=_FAST)
    try:
        topic = Topic("/status_text", "String")
        assert a.key_expr(topic) == "robot1/status_text"
        mine: list[str] = []
        theirs: list[str] = []
        subs = [same.create_subscription(topic, mine.append), other.create_subscription(topic, theirs.append)]
        pub = a.create_publisher(topic)
        assert wait_for(lambda: (pub.publish("hi"), bool(mine))[1], timeout=5.0, interval=0.05)
        time.sleep(0.2)
        assert theirs == []
        presence = a.declare_component("arm", on_transition=lambda t: True)
        assert wait_for(lambda: same.get_component_state("arm", timeout=0.5) is not None, timeout=5.0)
        assert other.get_component_state("arm", timeout=0.3) is None
        presence.close()
        for s in subs:
            s.close()
    finally:
        for t in (other, same, a):
            t.close()


def test_services_and_presence_answer_plain_zenoh_clients(trio: tuple[ZenohTransport, ZenohTransport, Any]) -> None:
    a, _, raw = trio
    name = _unique("adder")

    def add(req: dict[str, Any]) -> dict[str, Any]:
        if "x" not in req:
            raise KeyError("x")
        return {"sum": req["x"] + req.get("y", 0)}

    server = a.create_service(name, add)
    key = a.key_expr(name)

    def get(payload: bytes, encoding: str) -> list[Any]:
        return list(raw.get(key, payload=payload, encoding=encoding, timeout=5.0))

    assert wait_for(lambda: bool(get(msgpack.packb({"x": 1}), "application/msgpack")), timeout=5.0)
    [reply] = get(json.dumps({"x": 2, "y": 3}).encode(), "application/json")
    assert str(reply.ok.encoding) == "application/json"
    assert json.loads(reply.ok.payload.to_bytes()) == {"sum": 5}
    [reply] = get(msgpack.packb({"x": 2, "y": 3}), "application/msgpack")
    assert msgpack.unpackb(reply.ok.payload.to_bytes()) == {"sum": 5}
    [reply] = get(msgpack.packb({}), "application/msgpack")
    assert str(reply.err.encoding) == "application/msgpack;error"
    assert msgpack.unpackb(reply.err.payload.to_bytes()) == {"error": "KeyError: 'x'", "type": "KeyError"}
    [reply] = get(msgpack.packb([1, 2]), "application/msgpack")
    assert "a request must be a map" in msgpack.unpackb(reply.err.payload.to_bytes())["error"]
    server.close()

    presence = a.declare_component("gripper", on_transition=lambda t: t == "activate")
    presence.update(LifecycleState.ACTIVE, HealthStatus.COMPONENT_FAILURE, "jammed")
    replies: list[Any] = []
    # The new queryables reach the raw session within milliseconds; ask until they have.
    assert wait_for(lambda: bool(replies.extend(raw.get("@agents/state/gripper?format=json", timeout=2.0))
                                 or replies), timeout=5.0, interval=0.05)
    state = json.loads(replies[0].ok.payload.to_bytes())
    assert {k: state[k] for k in ("component", "lifecycle_state", "health", "message")} == {
        "component": "gripper", "lifecycle_state": "active", "health": "COMPONENT_FAILURE", "message": "jammed"}
    [reply] = list(raw.get("@agents/state/gripper", timeout=5.0))
    assert str(reply.ok.encoding) == "application/msgpack;ComponentStatus"
    tokens = [str(r.ok.key_expr) for r in raw.liveliness().get("@agents/components/**", timeout=2.0)]
    assert tokens == ["@agents/components/gripper"]
    presence.close()


def test_requests_fail_fast_and_clearly(trio: tuple[ZenohTransport, ZenohTransport, Any]) -> None:
    a, b, _ = trio
    start = time.monotonic()
    with pytest.raises(ServiceUnavailableError, match="nobody serves"):
        b.request(_unique("nobody"), {}, timeout=5.0)
    with pytest.raises(ServiceUnavailableError):
        b.request_transition("no_such_component", "activate", timeout=5.0)
    assert time.monotonic() - start < 2.0
    assert b.get_component_state("no_such_component", timeout=0.5) is None
    name = _unique("typed")
    a.create_service(name, lambda req: "not a dict")  # type: ignore[arg-type,return-value]
    deadline = time.monotonic() + 5.0
    while True:  # the new queryable reaches b within a few ms; retry until it has
        try:
            b.request(name, {}, timeout=5.0)
        except ServiceUnavailableError:
            assert time.monotonic() < deadline
            time.sleep(0.05)
        except RemoteError as exc:
            assert "not a dict" in str(exc)
            break


def test_closed_transport_refuses_every_call() -> None:
    port = free_tcp_port()
    t = ZenohTransport(listen=[f"tcp/127.0.0.1:{port}"])
    topic = Topic("after_close", "String")
    pub = t.create_publisher(topic)
    sub = t.create_subscription(topic, lambda v: None)
    presence = t.declare_component("late", on_transition=lambda _: True)
    t.close()
    t.close()  # idempotent
    calls = [
        lambda: pub.publish("x"),
        lambda: t.create_publisher(topic),
        lambda: t.create_subscription(topic, lambda v: None),
        lambda: t.create_service("srv", lambda r: r),
        lambda: t.request("srv", {}),
        lambda: t.declare_component("c", on_transition=lambda _: True),
        lambda: t.get_component_state("c"),
        lambda: t.request_transition("c", "activate"),
    ]
    for call in calls:
        with pytest.raises(TransportClosedError):
            call()
    sub.close()  # closing what the transport already closed is harmless
    presence.close()
    pub.close()


class _NoCodec(SupportedType):
    value_class = complex


def test_a_type_without_codec_is_refused_when_wiring() -> None:
    with ZenohTransport(listen=[f"tcp/127.0.0.1:{free_tcp_port()}"]) as t:
        topic = Topic("weird", _NoCodec)
        with pytest.raises(CodecError, match=r"register_codec\('_NoCodec'"):
            t.create_publisher(topic)
        with pytest.raises(CodecError, match="has no Zenoh codec"):
            t.create_subscription(topic, lambda v: None)


def test_config_validation() -> None:
    assert ZenohConfig(namespace="/robot1/arm/").namespace == "robot1/arm"
    for bad in ({"mode": "server"}, {"listen": "tcp/127.0.0.1:1"}, {"connect": ["127.0.0.1:7447"]},
                {"priorities": {"x": "urgent"}}, {"multicast_scouting": 1}, {"port": 0},
                {"config_file": "/nonexistent.json5"}, {"zenoh_options": {1: 2}}):
        with pytest.raises(ConfigError):
            ZenohConfig(**bad)
    with pytest.raises(TopicNameError):
        ZenohConfig(namespace="robot 1")
    with pytest.raises(ConfigError, match="unknown field"):
        ZenohTransport(listn=["tcp/127.0.0.1:1"])
    with pytest.raises(ConfigError, match="not both"):
        ZenohTransport(ZenohConfig(), mode="peer")


def test_multicast_scouting_is_off_unless_asked_and_then_logged(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    opened: list[Any] = []

    def fake_open(conf: Any) -> Any:
        opened.append(conf)
        raise zenoh.ZError("not opening anything in this test")

    monkeypatch.setattr(session_module.zenoh, "open", fake_open)
    with caplog.at_level(logging.WARNING, logger="agents_zenoh.session"), pytest.raises(Exception, match="not opening"):
        session_module.open_session(ZenohConfig(listen=["tcp/127.0.0.1:1"], multicast_scouting=True))
    assert "multicast scouting is ON" in caplog.text
    assert json.loads(opened[-1].get_json("scouting/multicast/enabled")) is True
    caplog.clear()
    with pytest.raises(Exception, match="not opening"):
        session_module.open_session(ZenohConfig(listen=["tcp/127.0.0.1:1"]))
    assert json.loads(opened[-1].get_json("scouting/multicast/enabled")) is False
    assert "multicast" not in caplog.text


def test_a_zenoh_config_file_is_the_base_and_scouting_stays_off(tmp_path: Any) -> None:
    path = tmp_path / "zenoh.json5"
    path.write_text('{mode: "client", connect: {endpoints: ["tcp/127.0.0.1:7999"]},\n'
                    ' scouting: {multicast: {enabled: true}}, // the file asks for it\n}')
    conf = session_module.zenoh_config(ZenohConfig(config_file=str(path)))
    assert json.loads(conf.get_json("mode")) == "client"
    assert json.loads(conf.get_json("connect/endpoints")) == ["tcp/127.0.0.1:7999"]
    assert json.loads(conf.get_json("scouting/multicast/enabled")) is False
    assert session_module.effective_mode(ZenohConfig(config_file=str(path))) == "client"
    override = session_module.zenoh_config(ZenohConfig(config_file=str(path), mode="peer", connect=[]))
    assert json.loads(override.get_json("mode")) == "peer"
    assert json.loads(override.get_json("connect/endpoints")) == []


def test_default_endpoints_rendezvous_on_loopback() -> None:
    port = free_tcp_port()
    first = ZenohTransport(port=port, zenoh_options=_FAST)  # takes tcp/127.0.0.1:<port>
    second = ZenohTransport(port=port, zenoh_options=_FAST)  # finds it taken and connects to it
    try:
        topic = Topic("rendezvous", "String")
        got: list[str] = []
        sub = second.create_subscription(topic, got.append)
        pub = first.create_publisher(topic)
        assert wait_for(lambda: (pub.publish("found you"), bool(got))[1], timeout=5.0, interval=0.05)
        sub.close()
    finally:
        second.close()
        first.close()


def test_resolved_by_name_with_options() -> None:
    port = free_tcp_port()
    transport = resolve_transport("zenoh", listen=[f"tcp/127.0.0.1:{port}"], namespace="ns")
    try:
        assert isinstance(transport, ZenohTransport)
        assert transport.capabilities.cross_process
        assert transport.name == "zenoh"
    finally:
        transport.close()
    with pytest.raises(ConfigError, match="bogus"):
        resolve_transport("zenoh", bogus=True)


def test_concurrent_publishers_keep_per_publisher_order(trio: tuple[ZenohTransport, ZenohTransport, Any]) -> None:
    a, b, _ = trio
    topic = Topic(_unique("concurrent"), "Int64", qos_profile=QoSConfig(depth=1000))
    got: list[int] = []
    sub = b.create_subscription(topic, got.append)
    pubs = [a.create_publisher(topic) for _ in range(2)]
    pubs[0].publish(-1)
    assert wait_for(lambda: got == [-1])
    threads = [threading.Thread(target=lambda p=p, k=k: [p.publish(k * 1000 + i) for i in range(100)])
               for k, p in enumerate(pubs)]
    for th in threads:
        th.start()
    for th in threads:
        th.join(timeout=10)
    assert wait_for(lambda: len(got) == 201, timeout=10.0)
    for k in range(2):
        assert [v for v in got if v // 1000 == k and v >= 0] == [k * 1000 + i for i in range(100)]
    sub.close()
