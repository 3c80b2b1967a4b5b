"""Goals on one Zenoh query stream (docs/zenoh-wire-format.md, "Goals"): cancel, late results, peers that misbehave.

The framework's client sends a goal as one query on ``<action>/@action/stream`` and reads the
decision, feedback, status and result as its replies. These tests check what that changes: a
goal cancelled mid-stream, a result asked for after the stream (or by another peer), a client
that goes away mid-goal, and replies that are hostile or oversized.
"""

from __future__ import annotations

import json
import secrets
import threading
import time
import uuid
from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip("zenoh")

import msgpack
import zenoh

from agents_core.errors import TransportError
from agents_core.testing.helpers import free_tcp_port, wait_for
from agents_core.transport.goals import GoalHandle, GoalStatus
from agents_zenoh.transport import ZenohTransport

from .goal_peers import ACTION, served_action
from .raw_goal_client import MSGPACK, open_peer, query

VLA = "VisionLanguageAction"


def _send(client: Any, goal: dict[str, Any], feedback: Any = None, timeout: float = 5.0) -> Any:
    """send_goal, retried while the peers are still connecting."""
    for _ in range(50):
        try:
            return client.send_goal(ACTION, VLA, goal, feedback=feedback, timeout=timeout)
        except TransportError:
            time.sleep(0.1)
    raise AssertionError("the action server was never reached")


def test_a_goal_cancelled_mid_stream_ends_canceled_with_its_feedback_on_the_stream() -> None:
    with served_action() as (server, client, peer):
        samples: list[str] = []
        sub = peer.session.declare_subscriber(f"{ACTION}/@action/feedback/*", lambda s: samples.append(str(s)))
        try:
            feedback: list[dict[str, Any]] = []
            goal = _send(client, {"task": "hold"}, feedback.append)
            assert goal.accepted
            assert wait_for(lambda: len(feedback) >= 3, timeout=10.0)
            assert goal.cancel(5.0) is True
            status, result = goal.result(10.0)
            assert status == GoalStatus.CANCELED and result["success"] is False
            # Every feedback the server produced came before the result, in order, on the stream.
            assert wait_for(lambda: len(feedback) == result["steps"], timeout=2.0)
            assert [f["step"] for f in feedback] == list(range(1, result["steps"] + 1))
            assert samples == []  # none as samples: the goal had its stream
            assert server.statistics().canceled == 1
        finally:
            sub.undeclare()


def test_a_stream_goal_is_executing_from_its_acceptance_and_peers_see_every_status_sample() -> None:
    """The decision carries EXECUTING; the status samples (the terminal one after the result) still all go out."""
    with served_action() as (_server, client, peer):
        statuses: list[int] = []

        def on_status(sample: zenoh.Sample) -> None:
            statuses.append(msgpack.unpackb(sample.payload.to_bytes())["status"])

        sub = peer.session.declare_subscriber(f"{ACTION}/@action/status/*", on_status)
        try:
            # The subscription reaches the server asynchronously: a first goal shows when it has.
            first = _send(client, {"task": "hold"})
            assert first.cancel(5.0) is True
            assert wait_for(lambda: int(GoalStatus.CANCELED) in statuses, timeout=5.0)
            statuses.clear()
            goal = _send(client, {"task": "hold"})
            assert goal.accepted
            assert goal.status == GoalStatus.EXECUTING  # from the decision, before any feedback
            assert goal.cancel(5.0) is True
            assert goal.result(10.0)[0] == GoalStatus.CANCELED
            want = [int(GoalStatus.EXECUTING), int(GoalStatus.CANCELING), int(GoalStatus.CANCELED)]
            # CANCELING (the cancel's thread) and CANCELED (the goal's) may go out in either order.
            wait_for(lambda: sorted(statuses) == want, timeout=5.0)
            assert sorted(statuses) == want
        finally:
            sub.undeclare()


def test_a_result_is_answered_to_a_late_result_query_after_the_stream_ended() -> None:
    with served_action() as (_server, client, peer):
        goal = _send(client, {"task": "hold"})
        time.sleep(0.1)
        assert goal.cancel(5.0) is True
        status, _result = goal.result(10.0)
        assert status == GoalStatus.CANCELED
        ok, doc = peer.ask("result", {"goal_id": goal.goal_id, "wait_s": 0.0})
        assert ok and doc["status"] == int(GoalStatus.CANCELED) and doc["result"]["success"] is False


def test_a_goal_that_outlives_its_stream_is_followed_by_result_queries(monkeypatch: pytest.MonkeyPatch) -> None:
    """The stream's time runs out mid-goal: feedback goes out as samples, the result comes from a result query."""
    from agents_zenoh import goal_client  # noqa: PLC0415

    monkeypatch.setattr(goal_client, "STREAM_S", 2.0)  # the server gives the stream up at 1 s

    def slow(handle: GoalHandle) -> dict[str, Any]:
        for step in range(1, 13):
            handle.wait_for_cancel(0.25)
            handle.publish_feedback({"step": step})
        return {"success": True, "steps": 12}

    port = free_tcp_port()
    with ZenohTransport(mode="peer", listen=[f"tcp/127.0.0.1:{port}"], connect=[], multicast_scouting=False) as a, \
            ZenohTransport(mode="peer", listen=[], connect=[f"tcp/127.0.0.1:{port}"], multicast_scouting=False) as b:
        a.create_action_server(ACTION, VLA, slow)
        feedback: list[dict[str, Any]] = []
        goal = _send(b, {"task": "x"}, feedback.append)
        assert goal.result(15.0) == (GoalStatus.SUCCEEDED, {"success": True, "message": "", "steps": 12})
        steps = [f["step"] for f in feedback]
        assert steps[:3] == [1, 2, 3]  # on the stream
        assert wait_for(lambda: feedback[-1]["step"] == 12, timeout=3.0)  # as samples, after it


def test_a_client_that_goes_away_mid_goal_leaves_the_server_serving() -> None:
    """The stream's client closes its session: the goal runs to its end, nothing is left held, others are served."""
    def short(handle: GoalHandle) -> dict[str, Any]:
        for step in range(1, 26):
            handle.wait_for_cancel(0.02)
            handle.publish_feedback({"step": step})
        return {"success": True, "steps": 25}

    port = free_tcp_port()
    with ZenohTransport(mode="peer", listen=[f"tcp/127.0.0.1:{port}"], connect=[], multicast_scouting=False) as a, \
            ZenohTransport(mode="peer", listen=[], connect=[f"tcp/127.0.0.1:{port}"], multicast_scouting=False) as b:
        server = a.create_action_server(ACTION, VLA, short)
        gone = open_peer(f"tcp/127.0.0.1:{port}")
        replies: list[dict[str, Any]] = []
        first = threading.Event()

        def on_reply(reply: zenoh.Reply) -> None:
            if reply.ok is not None:
                replies.append(msgpack.unpackb(reply.ok.payload.to_bytes()))
                first.set()

        # The connections are made asynchronously: wait until the raw peer reaches the server.
        assert wait_for(lambda: query(gone, f"{ACTION}/@action/result", msgpack.packb({"goal_id": "0" * 32}),
                                      1.0)[1] is not None, timeout=10.0)
        request = {"goal_id": uuid.uuid4().hex, "goal": {"task": "bye"}, "cancel_token": secrets.token_hex(16)}
        gone.get(f"{ACTION}/@action/stream", on_reply, payload=msgpack.packb(request), encoding=MSGPACK, timeout=30.0,
                 consolidation=zenoh.ConsolidationMode.NONE)  # every reply as it comes, not the latest at the end
        assert first.wait(5.0)
        # The acceptance carries the goal's first status (EXECUTING): one reply for both.
        assert replies[0] == {"kind": "goal", "accepted": True, "reason": "", "status": int(GoalStatus.EXECUTING)}
        assert wait_for(lambda: any(r.get("kind") == "feedback" for r in replies), timeout=5.0)
        gone.close()
        assert wait_for(lambda: server.statistics().succeeded == 1, timeout=10.0)
        assert server.statistics().accepted == 1
        goal = _send(b, {"task": "next"})
        assert goal.result(10.0)[0] == GoalStatus.SUCCEEDED


# -- a hostile server ----------------------------------------------------------------------------


def _listening_peer(port: int) -> zenoh.Session:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    conf.insert_json5("connect/endpoints", "[]")
    conf.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(conf)


@pytest.fixture
def hostile() -> Iterator[tuple[list[Any], ZenohTransport]]:
    """(script, client): a raw peer serving ``<action>/@action/stream`` by replying each item of ``script``.

    An item is a payload (bytes) or ``"err"`` for an error reply; the query ends after the last one.
    """
    port = free_tcp_port()
    session = _listening_peer(port)
    script: list[Any] = []

    def serve(query: zenoh.Query) -> None:
        with query:
            for item in script:
                if item == "err":
                    query.reply_err(msgpack.packb({"error": "boom", "type": "X"}), encoding=f"{MSGPACK};error")
                else:
                    query.reply(query.key_expr, item, encoding=MSGPACK)

    queryable = session.declare_queryable(f"{ACTION}/@action/stream", serve)
    client = ZenohTransport(mode="peer", listen=[], connect=[f"tcp/127.0.0.1:{port}"], multicast_scouting=False)
    try:
        yield script, client
    finally:
        client.close()
        queryable.undeclare()
        session.close()


def _doc(**fields: Any) -> bytes:
    return msgpack.packb(fields)


def test_hostile_replies_on_the_stream_are_counted_and_the_good_ones_delivered(
        hostile: tuple[list[Any], ZenohTransport]) -> None:
    script, client = hostile
    script += [
        _doc(kind="goal", accepted=True, reason=""),
        _doc(kind="feedback", feedback={"step": 1, "action": [], "status": "a"}),
        b"\xc1 not msgpack",
        _doc(kind="feedback", feedback=[1, 2, 3]),  # not a map
        _doc(kind="feedback", feedback={f"k{i}": i for i in range(5000)}),  # over the map length limit
        _doc(kind="surprise"),
        _doc(kind="status", status=99),
        "err",
        _doc(kind="feedback", feedback={"step": 2, "action": [], "status": "b"}),
        _doc(kind="result", status=4, result={"success": True, "message": "done", "steps": 2}),
        _doc(kind="feedback", feedback={"step": 3, "action": [], "status": "late"}),  # after the result: ignored
    ]
    feedback: list[dict[str, Any]] = []
    goal = _send(client, {"task": "x"}, feedback.append)
    assert goal.accepted
    assert goal.result(5.0) == (GoalStatus.SUCCEEDED, {"success": True, "message": "done", "steps": 2})
    assert wait_for(lambda: len(feedback) == 2, timeout=2.0)
    assert [f["step"] for f in feedback] == [1, 2]
    assert goal.feedback_errors == 6


def test_an_oversized_rejection_reason_is_cut(hostile: tuple[list[Any], ZenohTransport]) -> None:
    script, client = hostile
    script.append(_doc(kind="goal", accepted=False, reason="x" * 100_000))
    goal = _send(client, {"task": "x"})
    assert not goal.accepted and goal.status == GoalStatus.REJECTED
    assert goal.result(1.0)[1]["message"] == "x" * 1000


@pytest.mark.parametrize("first", [_doc(kind="feedback", feedback={}), b"\x93\x01\x02\x03", "err",
                                   _doc(kind="goal", accepted=True, reason="", pad={f"k{i}": i for i in range(5000)})])
def test_a_stream_that_does_not_begin_with_a_decision_fails_the_send(
        hostile: tuple[list[Any], ZenohTransport], first: Any) -> None:
    script, client = hostile
    script.append(first)
    for _ in range(50):
        try:
            client.send_goal(ACTION, VLA, {"task": "x"}, timeout=5.0)
        except TransportError as exc:
            if "nobody serves" in str(exc):  # still connecting
                time.sleep(0.1)
                continue
            assert "goal stream" in str(exc)
            return
        raise AssertionError("the goal was taken")
    raise AssertionError("the hostile server was never reached")


def test_a_stream_that_ends_without_a_result_ends_the_goal_aborted(hostile: tuple[list[Any], ZenohTransport]) -> None:
    """Accepted, then the query ends: the client asks for the result, nobody answers, the goal is ABORTED."""
    script, client = hostile
    script.append(_doc(kind="goal", accepted=True, reason=""))
    goal = _send(client, {"task": "x"})
    started = time.monotonic()
    status, result = goal.result(10.0)
    assert status == GoalStatus.ABORTED and "went away" in result["message"]
    assert time.monotonic() - started < 5.0


def test_a_stream_request_with_a_nan_stream_s_gets_an_error_reply() -> None:
    with served_action() as (server, _client, peer):
        request = {"goal_id": uuid.uuid4().hex, "goal": {"task": "x"}, "cancel_token": secrets.token_hex(16),
                   "stream_s": float("nan")}
        ok, answer = peer.ask("stream", request)
        assert not ok and "stream_s must be a number of seconds, not NaN" in answer["error"]
        ok, answer = peer.ask("stream", {**request, "stream_s": "long"})
        assert not ok and "stream_s must be a number of seconds" in answer["error"]
        assert server.statistics().decode_errors == 2 and server.statistics().accepted == 0


@pytest.mark.parametrize("inline", [False, True])
def test_stream_feedback_reaches_its_callback_in_order_on_the_thread_the_option_says(inline: bool) -> None:
    # Default: a goal-feedback thread of the goal's own. feedback_inline=True: the thread that reads the
    # stream's replies (Zenoh's own, not a Python thread started per goal), every message before the result.
    with served_action() as (_server, client, _peer):
        seen: list[tuple[int, str]] = []
        goal = None
        for _ in range(50):
            try:
                goal = client.send_goal(ACTION, VLA, {"task": "hold"}, timeout=5.0, feedback_inline=inline,
                                        feedback=lambda fb: seen.append((fb["step"], threading.current_thread().name)))
                break
            except TransportError:
                time.sleep(0.1)
        assert goal is not None and goal.accepted
        assert wait_for(lambda: len(seen) >= 3, timeout=10.0)
        assert goal.cancel(5.0) is True
        _status, result = goal.result(10.0)
        if inline:
            assert [s for s, _ in seen] == list(range(1, result["steps"] + 1))  # all in before the result
        else:
            assert wait_for(lambda: len(seen) == result["steps"], timeout=2.0)
        names = {name for _, name in seen}
        if inline:
            assert not any(n.startswith(("goal-feedback", "Thread-", "arm_goal")) for n in names), names
        else:
            assert all(n.startswith("goal-feedback:") for n in names), names
