"""ROS 2 actions on rmw_zenoh checked against oracles no one here wrote.

- CDR of every action message the server and client write equals ``rclpy.serialization.serialize_message`` of the
  same rclpy action message (but for alignment padding, see test_wire_oracles), and rclpy reads ours back;
- type hashes equal the installed ``share/agents_interfaces/action/VisionLanguageAction.json`` (all 13 generated
  types and the action itself) and ``share/action_msgs``;
- a live action server declares the five entities with rcl_action's names, rmw_zenoh's keys and those hashes.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

pytest.importorskip("rclpy", reason="needs the ros2 extra (the oracle)")
pytest.importorskip("rosbags", reason="needs the rmw_zenoh extra")
pytest.importorskip("agents_interfaces", reason="needs agents_interfaces")

from action_msgs.msg import GoalInfo, GoalStatus, GoalStatusArray
from action_msgs.srv import CancelGoal
from agents_interfaces.action import VisionLanguageAction
from builtin_interfaces.msg import Time
from rclpy.serialization import deserialize_message, serialize_message
from unique_identifier_msgs.msg import UUID

import agents_ros2.conversions  # noqa: F401  # imports rosidl_generator_py with its DeprecationWarning silenced
from agents_zenoh.rmw import actions
from agents_zenoh.rmw.typesupport import ros_types
from agents_zenoh.rmw.wire import data_key, parse_token

from .conftest import rmw_options

pytestmark = pytest.mark.ros2

VLA = "agents_interfaces/action/VisionLanguageAction"
GOAL_ID = "0123456789abcdef00112233445566ff"
STAMP = SimpleNamespace(sec=1_700_000_123, nanosec=456_789)
Impl = VisionLanguageAction.Impl


def _uuid() -> UUID:
    return UUID(uuid=list(bytes.fromhex(GOAL_ID)))


def _time() -> Time:
    return Time(sec=STAMP.sec, nanosec=STAMP.nanosec)


def _info() -> GoalInfo:
    return GoalInfo(goal_id=_uuid(), stamp=_time())


# (our message, its ROS type, the same message built with rclpy)
CASES: dict[str, tuple[Any, str, Any]] = {
    "send_goal_request": (
        actions.send_goal_request(GOAL_ID, {"task": "pick the cube", "max_steps": 7}), f"{VLA}_SendGoal_Request",
        Impl.SendGoalService.Request(goal_id=_uuid(),
                                     goal=VisionLanguageAction.Goal(task="pick the cube", max_steps=7))),
    "send_goal_response": (
        actions.send_goal_response(True, STAMP), f"{VLA}_SendGoal_Response",
        Impl.SendGoalService.Response(accepted=True, stamp=_time())),
    "get_result_request": (
        actions.result_request(GOAL_ID), f"{VLA}_GetResult_Request", Impl.GetResultService.Request(goal_id=_uuid())),
    "get_result_response": (
        actions.result_response(4, {"success": True, "message": "done", "steps": 5}), f"{VLA}_GetResult_Response",
        Impl.GetResultService.Response(status=4, result=VisionLanguageAction.Result(success=True, message="done",
                                                                                    steps=5))),
    "feedback": (
        actions.feedback_message(GOAL_ID, {"step": 3, "action": [3.0, -1.5, 0.25], "status": "moving"}),
        f"{VLA}_FeedbackMessage",
        Impl.FeedbackMessage(goal_id=_uuid(), feedback=VisionLanguageAction.Feedback(
            step=3, action=[3.0, -1.5, 0.25], status="moving"))),
    "status": (
        actions.status_array([(GOAL_ID, STAMP, 2), ("f" * 32, STAMP, 4)]), "action_msgs/msg/GoalStatusArray",
        GoalStatusArray(status_list=[GoalStatus(goal_info=_info(), status=2),
                                     GoalStatus(goal_info=GoalInfo(goal_id=UUID(uuid=[255] * 16), stamp=_time()),
                                                status=4)])),
    "cancel_request": (
        actions.cancel_request(GOAL_ID), "action_msgs/srv/CancelGoal_Request",
        CancelGoal.Request(goal_info=GoalInfo(goal_id=_uuid(), stamp=Time(sec=0, nanosec=0)))),
    "cancel_response": (
        actions.cancel_response(0, [(GOAL_ID, STAMP)]), "action_msgs/srv/CancelGoal_Response",
        CancelGoal.Response(return_code=0, goals_canceling=[_info()])),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_action_cdr_equals_rclpy_and_reads_back(case: str) -> None:
    ours, ros_type, message = CASES[case]
    payload = ros_types().serialize(ours, ros_type)
    reference = serialize_message(message)
    assert len(reference) - 16 <= len(payload) <= len(reference)
    differ = [i for i, (a, b) in enumerate(zip(payload, reference, strict=False)) if a != b]
    assert all(payload[i] == 0 for i in differ), differ  # alignment padding only (Fast CDR leaves it unset)
    assert deserialize_message(payload, type(message)) == message
    # and rclpy's bytes read back through ours: the same fields
    back = ros_types().deserialize(reference[:len(payload)], ros_type)
    assert ros_types().serialize(back, ros_type) == payload


def _installed(pkg: str, kind: str, name: str) -> dict[str, str]:
    roots = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p] + [sys.prefix]
    for root in roots:
        path = Path(root) / "share" / pkg / kind / f"{name}.json"
        if path.is_file():
            return {e["type_name"]: e["hash_string"] for e in json.loads(path.read_text())["type_hashes"]}
    raise AssertionError(f"no installed type description for {pkg}/{kind}/{name}")


def test_action_type_hashes_equal_the_installed_descriptions() -> None:
    expected = {**_installed("agents_interfaces", "action", "VisionLanguageAction"),
                **_installed("action_msgs", "srv", "CancelGoal"), **_installed("action_msgs", "msg", "GoalStatusArray")}
    generated = [t for t in expected if t.startswith(VLA)]
    assert len(generated) == 13  # the action and its 12 generated types
    for type_name, hash_string in expected.items():
        assert ros_types().type_hash(type_name) == hash_string, type_name


def test_a_live_action_server_declares_rcl_actions_entities(router: str) -> None:
    from agents_zenoh.rmw.transport import RmwZenohTransport  # noqa: PLC0415

    server_side = RmwZenohTransport(**rmw_options(router))
    watcher = RmwZenohTransport(**rmw_options(router))
    try:
        server = server_side.create_action_server("arm/grip", "VisionLanguageAction", lambda h: {"success": True})
        types = ros_types()
        wanted = {  # entity name -> (kind, ROS type)
            "/arm/grip/_action/send_goal": ("SS", f"{VLA}_SendGoal"),
            "/arm/grip/_action/cancel_goal": ("SS", "action_msgs/srv/CancelGoal"),
            "/arm/grip/_action/get_result": ("SS", f"{VLA}_GetResult"),
            "/arm/grip/_action/feedback": ("MP", f"{VLA}_FeedbackMessage"),
            "/arm/grip/_action/status": ("MP", "action_msgs/msg/GoalStatusArray"),
        }
        found: dict[str, Any] = {}
        deadline = time.monotonic() + 5.0
        while len(found) < len(wanted) and time.monotonic() < deadline:
            for token in watcher.driver._graph.tokens(0.1):
                parsed = parse_token(token)
                if parsed.name in wanted:
                    found[parsed.name] = parsed
        assert set(found) == set(wanted)
        for name, (kind, ros_type) in wanted.items():
            entity = found[name]
            pkg, sub, short = ros_type.split("/")
            assert entity.kind == kind
            assert entity.ros_type == f"{pkg}::{sub}::dds_::{short}_"
            assert entity.type_hash == types.type_hash(ros_type)
            assert data_key(21, name, ros_type, entity.type_hash).startswith(f"21/arm/grip/_action/{name[18:]}/")
        status_qos = found["/arm/grip/_action/status"].qos
        assert status_qos is not None and status_qos.durability == 1  # transient local, as rcl_action has it
        server.close()
    finally:
        watcher.close()
        server_side.close()
