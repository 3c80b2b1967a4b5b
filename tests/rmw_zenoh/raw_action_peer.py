"""A ROS 2 action peer in rmw_zenoh's format, from zenoh-python, rosbags, xxhash and the installed type descriptions.

None of agents_zenoh's code: the action's generated types are written here from ``VisionLanguageAction.action`` as
rosidl generates them, keys and tokens by hand, type hashes read from ``share/.../VisionLanguageAction.json``.
Usage: ``python raw_action_peer.py ROUTER DOMAIN MODE ACTION``:

- ``client``: send one goal ``{"task": "raw", "max_steps": 3}`` to ``/ACTION``, read its feedback, ask for its result;
  print one JSON line (accepted, the result's status and fields, the feedback steps seen, whether seq/GID were echoed);
- ``serve``: serve ``/ACTION`` until stdin closes: accept every goal, publish feedback steps 0..2, succeed with
  ``{"success": true, "message": "raw did <task>", "steps": 3}``; a goal with task ``"hang"`` never ends.
"""

from __future__ import annotations

import json
import sys
import threading
import time
import uuid
from typing import Any

import numpy as np
import zenoh
from raw_wire import SHARE, attachment, dds, gid, open_session, read_attachment, store
from rosbags.typesys import get_types_from_msg

ROUTER, DOMAIN, MODE, ACTION = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
ROS = "agents_interfaces/action/VisionLanguageAction"
HASHES = {e["type_name"]: e["hash_string"] for e in json.loads(
    (SHARE / "agents_interfaces" / "action" / "VisionLanguageAction.json").read_text())["type_hashes"]}

# The generated types, as rosidl writes them (names here are ours: only the CDR layout and the hashes matter).
goal_text, result_text, feedback_text = (SHARE / "agents_interfaces" / "action" /
                                         "VisionLanguageAction.action").read_text().split("\n---\n")
P = "agents_interfaces/msg/Raw"
for name, text in {"Goal": goal_text, "Result": result_text, "Feedback": feedback_text,
                   "SendReq": f"unique_identifier_msgs/UUID goal_id\n{P}Goal goal",
                   "SendRes": "bool accepted\nbuiltin_interfaces/Time stamp",
                   "ResultReq": "unique_identifier_msgs/UUID goal_id",
                   "ResultRes": f"int8 status\n{P}Result result",
                   "FeedbackMsg": f"unique_identifier_msgs/UUID goal_id\n{P}Feedback feedback"}.items():
    store.register(get_types_from_msg(text, P + name))
T = store.types


def cdr(message: Any, name: str) -> bytes:
    return bytes(store.serialize_cdr(message, P + name))


def uncdr(data: bytes, name: str) -> Any:
    return store.deserialize_cdr(data, P + name)


session = open_session(ROUTER)
zid = str(session.zid())
node = "raw_action_peer"
tokens = [session.liveliness().declare_token(f"@ros2_lv/{DOMAIN}/{zid}/0/0/NN/%/%/{node}")]
ids = iter(range(1, 100))


def entity(kind: str, part: str, ros_type: str) -> tuple[str, bytes]:
    name = f"/{ACTION}/_action/{part}"
    h = HASHES[ros_type]
    token = (f"@ros2_lv/{DOMAIN}/{zid}/0/{next(ids)}/{kind}/%/%/{node}/{name.replace('/', '%')}/{dds(ros_type)}/{h}"
             "/::,10:,:,:,,")
    tokens.append(session.liveliness().declare_token(token))
    return f"{DOMAIN}/{name.strip('/')}/{dds(ros_type)}/{h}", gid(token)


def uuid_msg(raw: bytes) -> Any:
    return store.types["unique_identifier_msgs/msg/UUID"](uuid=np.frombuffer(raw, dtype=np.uint8))


def query(key: str, g: bytes, seq: int, body: bytes, timeout: float) -> tuple[bytes, bool] | None:
    for reply in session.get(key, payload=body, attachment=attachment(seq, g), timeout=timeout,
                             target=zenoh.QueryTarget.ALL_COMPLETE):
        if reply.ok is not None:
            echo_seq, _stamp, echo_gid = read_attachment(reply.ok.attachment)
            return reply.ok.payload.to_bytes(), echo_seq == seq and echo_gid == g
    return None


if MODE == "client":
    goal_id = uuid.uuid4().bytes
    send_key, send_gid = entity("SC", "send_goal", f"{ROS}_SendGoal")
    result_key, result_gid = entity("SC", "get_result", f"{ROS}_GetResult")
    feedback_key, _ = entity("MS", "feedback", f"{ROS}_FeedbackMessage")
    steps: list[int] = []

    def on_feedback(sample: zenoh.Sample) -> None:
        read_attachment(sample.attachment)
        msg = uncdr(sample.payload.to_bytes(), "FeedbackMsg")
        if bytes(msg.goal_id.uuid) == goal_id:
            steps.append(int(msg.feedback.step))

    sub = session.declare_subscriber(feedback_key, on_feedback)
    time.sleep(0.3)
    request = T[P + "SendReq"](goal_id=uuid_msg(goal_id), goal=T[P + "Goal"](task="raw", max_steps=3))
    answer = None
    for attempt in range(1, 30):
        answer = query(send_key, send_gid, attempt, cdr(request, "SendReq"), 2.0)
        if answer is not None:
            break
        time.sleep(0.2)
    assert answer is not None, "no reply to send_goal"
    accepted = bool(uncdr(answer[0], "SendRes").accepted)
    out: dict[str, Any] = {"accepted": accepted, "send_echoed": answer[1]}
    if accepted:
        got = query(result_key, result_gid, 1, cdr(T[P + "ResultReq"](goal_id=uuid_msg(goal_id)), "ResultReq"), 10.0)
        assert got is not None, "no reply to get_result"
        response = uncdr(got[0], "ResultRes")
        time.sleep(0.2)
        out.update(status=int(response.status), success=bool(response.result.success),
                   message=response.result.message, steps=int(response.result.steps), result_echoed=got[1],
                   feedback=steps)
    print(json.dumps(out), flush=True)
    sub.undeclare()
elif MODE == "serve":
    feedback_key, feedback_gid = entity("MP", "feedback", f"{ROS}_FeedbackMessage")
    feedback_pub = session.declare_publisher(feedback_key)
    results: dict[bytes, Any] = {}
    ended: dict[bytes, threading.Event] = {}
    seq = iter(range(1, 1000))

    def run(goal_id: bytes, task: str) -> None:
        if task == "hang":  # never ends: the test kills this peer mid-goal
            return
        for step in range(3):
            fb = T[P + "FeedbackMsg"](goal_id=uuid_msg(goal_id), feedback=T[P + "Feedback"](
                step=step, action=np.array([float(step), 0.5]), status="raw moving"))
            feedback_pub.put(cdr(fb, "FeedbackMsg"), attachment=attachment(next(seq), feedback_gid))
            time.sleep(0.05)
        results[goal_id] = T[P + "ResultRes"](status=4, result=T[P + "Result"](
            success=True, message=f"raw did {task}", steps=3))
        ended[goal_id].set()

    def on_send(q: zenoh.Query) -> None:
        with q:
            s, _stamp, client = read_attachment(q.attachment)
            assert q.payload is not None
            request = uncdr(q.payload.to_bytes(), "SendReq")
            goal_id = bytes(request.goal_id.uuid)
            ended[goal_id] = threading.Event()
            now = time.time_ns()
            stamp = store.types["builtin_interfaces/msg/Time"](sec=now // 10**9, nanosec=now % 10**9)
            q.reply(send_key, cdr(T[P + "SendRes"](accepted=True, stamp=stamp), "SendRes"),
                    attachment=attachment(s, client))
        threading.Thread(target=run, args=(goal_id, request.goal.task), daemon=True).start()

    def on_result(q: zenoh.Query) -> None:
        def later() -> None:
            with q:
                s, _stamp, client = read_attachment(q.attachment)
                assert q.payload is not None
                goal_id = bytes(uncdr(q.payload.to_bytes(), "ResultReq").goal_id.uuid)
                event = ended.get(goal_id)
                if event is not None and event.wait(5.0):
                    q.reply(result_key, cdr(results[goal_id], "ResultRes"), attachment=attachment(s, client))
        threading.Thread(target=later, daemon=True).start()

    send_key, _ = entity("SS", "send_goal", f"{ROS}_SendGoal")
    result_key, _ = entity("SS", "get_result", f"{ROS}_GetResult")
    queryables = [session.declare_queryable(send_key, on_send, complete=True),
                  session.declare_queryable(result_key, on_result, complete=True)]
    print("ready", flush=True)
    sys.stdin.read()
    for queryable in queryables:
        queryable.undeclare()
    feedback_pub.undeclare()
for token in tokens:
    token.undeclare()
session.close()
