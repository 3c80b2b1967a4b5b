"""Hostile input on rmw_zenoh: malformed CDR, wrong type hashes, bogus liveliness tokens, garbage attachments.

Each is refused and counted (a subscription's decode_errors, the driver's refused_requests), never delivered,
never a crash or a component's state change; good traffic keeps flowing.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from typing import Any

import pytest

from agents_core.supported_types import get_type
from agents_core.topics import Topic

from .conftest import rmw_options

pytestmark = pytest.mark.zenoh

zenoh = pytest.importorskip("zenoh")
pytest.importorskip("rosbags", reason="needs the rmw_zenoh extra")

from agents_zenoh.rmw.codec import codec_for  # noqa: E402
from agents_zenoh.rmw.transport import RmwZenohTransport  # noqa: E402
from agents_zenoh.rmw.typesupport import ros_types  # noqa: E402
from agents_zenoh.rmw.wire import data_key, encode_attachment  # noqa: E402


def _plain_session(router: str) -> Any:
    """A plain Zenoh peer on loopback, connected to ``router`` (multicast scouting off)."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("connect/endpoints", json.dumps([router]))
    conf.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')
    conf.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(conf)


@pytest.fixture
def attacker(router: str) -> Iterator[Any]:
    """A plain Zenoh session on the same router."""
    session = _plain_session(router)
    try:
        yield session
    finally:
        session.close()


@pytest.fixture
def ours(router: str) -> Iterator[Any]:
    transport = RmwZenohTransport(**rmw_options(router))
    try:
        yield transport
    finally:
        transport.close()


def _wait(predicate: Any, timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.02)
    return bool(predicate())


def test_bad_samples_are_refused_and_counted(ours: Any, attacker: Any) -> None:
    got: list[str] = []
    sub = ours.create_subscription(Topic("victim", get_type("String")), got.append)
    codec = codec_for(get_type("String"))
    key = data_key(21, "/victim", codec.ros_type, codec.type_hash)
    good = codec.encode("good")
    att = encode_attachment(1, time.time_ns(), bytes(16))
    wrong_hash = data_key(21, "/victim", codec.ros_type, "RIHS01_" + "0" * 64)
    wrong_type = data_key(21, "/victim", "std_msgs/msg/Int32", codec_for(get_type("Int32")).type_hash)
    bad = [
        (key, good, None),                                   # no attachment
        (key, good, b"\x01\x02\x03"),                        # garbage attachment
        (key, good, att[:-1] + b""),                         # truncated attachment
        (key, b"\x00\x01\x00\x00\xff\xff\xff\x7fhi", att),   # string length far past the payload
        (key, b"\x07\x07", att),                             # not even a CDR header
        (key, b"\x00\x01\x00\x00\x03\x00\x00\x00\xff\xfe\x00", att),  # not UTF-8
        (wrong_hash, good, att),
        (wrong_type, codec_for(get_type("Int32")).encode(5), att),
    ]
    time.sleep(0.5)
    for k, payload, attachment in bad:
        attacker.put(k, payload, **({"attachment": attachment} if attachment is not None else {}))
    attacker.put(key, good, attachment=att)
    assert _wait(lambda: got == ["good"] and sub.statistics().decode_errors == len(bad))
    time.sleep(0.2)
    assert got == ["good"]
    assert sub.statistics().decode_errors == len(bad)


def test_bogus_tokens_do_not_break_discovery(ours: Any, attacker: Any) -> None:
    ours.create_publisher(Topic("real_topic", get_type("String")))
    bogus = ["@ros2_lv/21/x/y", "@ros2_lv/21/z/0/0/MP/%/%/n/%t/T/H/not-a-qos",
             "@ros2_lv/21/z/0/0/QQ/%/%/n", "@ros2_lv/21/z/0/0/MP/%/%/n/%t/T/H/99::,:,:,:,,/extra",
             "@ros2_lv/21/z/0/0/MS/%/%/n/%t/T/H/1:2:3:4:5:6"]
    tokens = [attacker.liveliness().declare_token(t) for t in bogus]
    try:
        graph = ours.discover(1.0)
        assert [t.name for t in graph.topics] == ["real_topic"]
    finally:
        for token in tokens:
            token.undeclare()


def test_bad_queries_are_refused_and_counted_without_a_state_change(ours: Any, attacker: Any) -> None:
    transitions: list[str] = []
    ours.declare_component("victim_node", on_transition=lambda t: transitions.append(t) or True)
    ours.create_service("victim_srv", lambda request: {"ok": True})
    types = ros_types()
    change = data_key(21, "/victim_node/change_state", "lifecycle_msgs/srv/ChangeState",
                      types.type_hash("lifecycle_msgs/srv/ChangeState"))
    call = data_key(21, "/victim_srv", "agents_interfaces/srv/JsonCall",
                    types.type_hash("agents_interfaces/srv/JsonCall"))
    att = encode_attachment(1, time.time_ns(), bytes(16))
    cases = [(change, b"\x00\x01\x00\x00\x01", None), (change, b"\x00\x01\x00\x00", b"junk"),
             (change, b"garbage", att), (call, b"\x00\x01\x00\x00\xff\xff\xff\xff", att), (call, b"", att)]
    time.sleep(0.3)
    for key, payload, attachment in cases:
        replies = list(attacker.get(key, payload=payload, timeout=2.0,
                                    **({"attachment": attachment} if attachment is not None else {})))
        assert all(r.ok is None for r in replies)
    assert ours.driver.refused_requests == len(cases)
    assert transitions == []
    assert ours.request("victim_srv", {}, timeout=3.0) == {"ok": True}


def test_bad_action_requests_are_refused_and_counted(ours: Any, attacker: Any) -> None:
    from agents_zenoh.rmw import actions  # noqa: PLC0415

    server = ours.create_action_server("victim_arm", "VisionLanguageAction",
                                       lambda handle: (handle.wait_for_cancel(2.0), {"success": True})[1])
    types = ros_types()
    vla = "agents_interfaces/action/VisionLanguageAction"

    def key(part: str, ros_type: str) -> str:
        return data_key(21, f"/victim_arm/_action/{part}", ros_type, types.type_hash(ros_type))

    send = key("send_goal", f"{vla}_SendGoal")
    att = encode_attachment(1, time.time_ns(), bytes(16))
    good = types.serialize(actions.send_goal_request("ab" * 16, {"task": "t", "max_steps": 1}),
                           f"{vla}_SendGoal_Request")
    cases = [(send, b"garbage", att), (send, good[:9], att), (send, good, None),
             (key("get_result", f"{vla}_GetResult"), b"\x00\x01\x00\x00\x01", att),
             (key("cancel_goal", "action_msgs/srv/CancelGoal"), b"", att)]
    time.sleep(0.3)
    for k, payload, attachment in cases:
        replies = list(attacker.get(k, payload=payload, timeout=2.0,
                                    **({"attachment": attachment} if attachment is not None else {})))
        assert all(r.ok is None for r in replies)
    assert server.statistics().decode_errors == len(cases)

    def accepted(body: bytes) -> bool:
        replies = [r for r in attacker.get(send, payload=body, attachment=att, timeout=3.0) if r.ok is not None]
        assert len(replies) == 1
        return bool(types.deserialize(replies[0].ok.payload.to_bytes(), f"{vla}_SendGoal_Response").accepted)

    assert accepted(good)  # still serving
    assert not accepted(good)  # the same goal id again: rejected
    stats = server.statistics()
    assert (stats.accepted, stats.rejected, stats.decode_errors) == (1, 1, len(cases))
    server.close()


def test_a_flood_of_tokens_is_bounded_and_counted(router: str, attacker: Any) -> None:
    """A peer announcing tokens without end cannot grow the graph: past its bound new tokens are dropped and
    counted, ours are still held (our services still found), and room comes back as tokens are withdrawn."""
    transport = RmwZenohTransport(**rmw_options(router, max_graph_tokens=40))
    try:
        graph = transport.driver.graph
        assert _wait(lambda: len(graph.tokens(0)) >= 1)
        flood = [attacker.liveliness().declare_token(f"@ros2_lv/21/{'f' * 32}/9/{i}/MP/%/%/flood/%flood{i}/"
                                                     f"std_msgs::msg::dds_::String_/RIHS01_{'0' * 64}/::,10:,:,:,,")
                 for i in range(100)]
        try:
            assert _wait(lambda: len(graph.tokens(0)) + graph.dropped >= 100)
            held = graph.tokens(0)
            assert len(held) == 40
            flooded = sum(1 for t in held if "/flood/" in t)
            assert graph.dropped == 100 - flooded and graph.dropped >= 60
            transport.create_service("still_here", lambda request: {"ok": True})  # our own tokens: always held
            assert _wait(lambda: any("still_here" in t for t in graph.tokens(0)))
            assert transport.driver.served("/still_here", "agents_interfaces/srv/JsonCall")
            assert transport.request("still_here", {}, timeout=3.0) == {"ok": True}
            assert len(transport.discover(0.1).topics) <= 40
        finally:
            for token in flood:
                token.undeclare()
        assert _wait(lambda: not any("/flood/" in t for t in graph.tokens(0)))
        late = attacker.liveliness().declare_token("@ros2_lv/21/" + "e" * 32 + "/0/0/NN/%/%/late_node")
        try:
            assert _wait(lambda: any(t.endswith("/late_node") for t in graph.tokens(0)))  # room again
        finally:
            late.undeclare()
    finally:
        transport.close()


def _flood_key(zid: str, i: int) -> str:
    return (f"@ros2_lv/21/{zid}/9/{i}/MP/%/%/flood/%flood{i}/std_msgs::msg::dds_::String_/RIHS01_{'0' * 64}"
            "/::,10:,:,:,,")


def test_tokens_that_spoof_our_zid_are_bounded_like_any_other(router: str, attacker: Any) -> None:
    """"Ours" is what this driver declared, not what carries its zid: anyone can write our (public) zid into a
    token key (review s9, finding 2)."""
    transport = RmwZenohTransport(**rmw_options(router, max_graph_tokens=40))
    try:
        graph = transport.driver.graph
        zid = str(transport.driver._session.zid())
        assert _wait(lambda: len(graph.tokens(0)) >= 1)
        flood = [attacker.liveliness().declare_token(_flood_key(zid, i)) for i in range(300)]
        try:
            assert _wait(lambda: sum("/flood/" in t for t in graph.tokens(0)) + graph.dropped >= 300)
            held = graph.tokens(0)
            assert len(held) <= 40 and graph.dropped >= 260, (len(held), graph.dropped)
            transport.create_service("ours_still", lambda request: {"ok": True})  # declared by us: held
            assert _wait(lambda: any("ours_still" in t for t in graph.tokens(0)))
            assert transport.request("ours_still", {}, timeout=3.0) == {"ok": True}
        finally:
            for token in flood:
                token.undeclare()
    finally:
        transport.close()


def test_a_token_dropped_in_a_flood_is_seen_once_the_flood_ends(router: str, attacker: Any) -> None:
    """Zenoh announces a live token once: when room comes back after drops, the graph is read again (review s9,
    finding 7)."""
    transport = RmwZenohTransport(**rmw_options(router, max_graph_tokens=40))
    honest = _plain_session(router)
    try:
        graph = transport.driver.graph
        flood = [attacker.liveliness().declare_token(_flood_key("f" * 32, i)) for i in range(100)]
        try:
            assert _wait(lambda: sum("/flood/" in t for t in graph.tokens(0)) + graph.dropped >= 100)
            before = graph.dropped
            legit = honest.liveliness().declare_token("@ros2_lv/21/" + "e" * 32 + "/0/0/NN/%/%/honest_node")
            assert _wait(lambda: graph.dropped == before + 1)  # it came in the flood, and was dropped
            assert not any(t.endswith("/honest_node") for t in graph.tokens(0))
        finally:
            for token in flood:
                token.undeclare()
        assert _wait(lambda: not any("/flood/" in t for t in graph.tokens(0)))
        started = time.monotonic()
        assert _wait(lambda: any(t.endswith("/honest_node") for t in graph.tokens(0)), timeout=5.0), \
            "the token dropped during the flood is still unseen"
        print(f"seen {time.monotonic() - started:.2f} s after the flood was withdrawn; re-reads: {graph.resyncs}")
        assert graph.resyncs >= 1
        legit.undeclare()
        assert _wait(lambda: not any(t.endswith("/honest_node") for t in graph.tokens(0)))  # no stale entry
    finally:
        transport.close()
        honest.close()


@pytest.mark.parametrize("bound", [True, False, 0, -1, 1.5, "40", None])
def test_max_graph_tokens_must_be_an_int_of_at_least_one(bound: object) -> None:
    from agents_core.errors import ConfigError  # noqa: PLC0415

    with pytest.raises(ConfigError, match="max_graph_tokens"):
        RmwZenohTransport(connect=["tcp/127.0.0.1:9"], listen=[], router_timeout=0, max_graph_tokens=bound)
