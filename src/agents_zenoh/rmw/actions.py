"""ROS 2 actions as rmw_zenoh carries them: the message plumbing shared by action servers and goal clients.

An action ``/<name>`` of type ``pkg/action/<A>`` is three services and two topics (as rcl_action
names them, and rmw_zenoh maps them like any other service and topic):

- ``/<name>/_action/send_goal`` (``pkg/action/<A>_SendGoal``): goal id + goal -> accepted + stamp;
- ``/<name>/_action/cancel_goal`` (``action_msgs/srv/CancelGoal``);
- ``/<name>/_action/get_result`` (``pkg/action/<A>_GetResult``): goal id -> status + result, answered
  once the goal has ended;
- ``/<name>/_action/feedback`` (``pkg/action/<A>_FeedbackMessage``): goal id + feedback;
- ``/<name>/_action/status`` (``action_msgs/msg/GoalStatusArray``, transient local, depth 1).

Messages are built as attribute objects (:class:`types.SimpleNamespace`) that
:meth:`~agents_zenoh.rmw.typesupport.RosTypes.serialize` writes by field name; received ones are the
``rosbags`` dataclasses, read back into the core's plain dicts by :func:`to_dict`.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import zenoh

from agents_core.errors import TransportError
from agents_core.transport.goals import ActionType

from .entities import Node, absolute
from .typesupport import ros_types
from .wire import Qos, decode_attachment

__all__ = [
    "CANCEL_GOAL",
    "FEEDBACK_QOS",
    "STATUS_ARRAY",
    "STATUS_QOS",
    "ActionNames",
    "RawPublisher",
    "RawSubscription",
    "cancel_request",
    "cancel_response",
    "feedback_message",
    "goal_uuid",
    "result_request",
    "result_response",
    "send_goal_request",
    "send_goal_response",
    "stamp_now",
    "status_array",
    "to_dict",
    "uuid_hex",
]

CANCEL_GOAL = "action_msgs/srv/CancelGoal"
STATUS_ARRAY = "action_msgs/msg/GoalStatusArray"
#: rcl_action's defaults: feedback as topics default (reliable, volatile, keep last 10); status
#: reliable, transient local, keep last 1.
FEEDBACK_QOS = Qos(depth=10)
STATUS_QOS = Qos(durability=1, depth=1)


class ActionNames:
    """The ROS type and the five entity names of one action."""

    def __init__(self, name: str, definition: ActionType) -> None:
        parts = definition.ros_type.split("/")
        if len(parts) != 3 or parts[1] != "action" or not all(parts):
            raise TransportError(f"action type {definition.name!r} has no ROS 2 type (ros_type "
                                 f"{definition.ros_type!r}; expected 'package/action/Name')")
        self.base = definition.ros_type
        ros_types().ensure(self.base)
        prefix = absolute(name) + "/_action/"
        self.send_goal = prefix + "send_goal"
        self.cancel_goal = prefix + "cancel_goal"
        self.get_result = prefix + "get_result"
        self.feedback = prefix + "feedback"
        self.status = prefix + "status"

    @property
    def send_goal_type(self) -> str:
        """``pkg/action/<A>_SendGoal``."""
        return f"{self.base}_SendGoal"

    @property
    def get_result_type(self) -> str:
        """``pkg/action/<A>_GetResult``."""
        return f"{self.base}_GetResult"

    @property
    def feedback_type(self) -> str:
        """``pkg/action/<A>_FeedbackMessage``."""
        return f"{self.base}_FeedbackMessage"


def goal_uuid(goal_id: str) -> SimpleNamespace:
    """A ``unique_identifier_msgs/msg/UUID`` of a 32-hex-digit goal id."""
    return SimpleNamespace(uuid=bytes.fromhex(goal_id))


def uuid_hex(uuid_msg: Any) -> str:
    """The goal id (32 hex digits) of a received UUID message; TransportError if it is not 16 bytes."""
    raw = bytes(bytearray(int(b) & 0xFF for b in uuid_msg.uuid))
    if len(raw) != 16:
        raise TransportError(f"a goal id must be 16 bytes, got {len(raw)}")
    return raw.hex()


def stamp_now() -> SimpleNamespace:
    """A ``builtin_interfaces/msg/Time`` of now."""
    ns = time.time_ns()
    return SimpleNamespace(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def send_goal_request(goal_id: str, goal: dict[str, Any]) -> SimpleNamespace:
    """``<A>_SendGoal_Request``: the goal id and the goal's fields."""
    return SimpleNamespace(goal_id=goal_uuid(goal_id), goal=SimpleNamespace(**goal))


def send_goal_response(accepted: bool, stamp: SimpleNamespace) -> SimpleNamespace:
    """``<A>_SendGoal_Response``."""
    return SimpleNamespace(accepted=accepted, stamp=stamp)


def result_request(goal_id: str) -> SimpleNamespace:
    """``<A>_GetResult_Request``."""
    return SimpleNamespace(goal_id=goal_uuid(goal_id))


def result_response(status: int, result: dict[str, Any]) -> SimpleNamespace:
    """``<A>_GetResult_Response``: the wire status (``action_msgs/msg/GoalStatus``) and the result's fields."""
    return SimpleNamespace(status=status, result=SimpleNamespace(**result))


def feedback_message(goal_id: str, feedback: dict[str, Any]) -> SimpleNamespace:
    """``<A>_FeedbackMessage``."""
    return SimpleNamespace(goal_id=goal_uuid(goal_id), feedback=SimpleNamespace(**feedback))


def status_array(goals: list[tuple[str, SimpleNamespace, int]]) -> SimpleNamespace:
    """``action_msgs/msg/GoalStatusArray`` of ``(goal id, stamp, status)``."""
    return SimpleNamespace(status_list=[SimpleNamespace(goal_info=SimpleNamespace(goal_id=goal_uuid(g), stamp=stamp),
                                                        status=status) for g, stamp, status in goals])


def cancel_request(goal_id: str) -> SimpleNamespace:
    """``action_msgs/srv/CancelGoal_Request`` for one goal (stamp zero: that goal only)."""
    return SimpleNamespace(goal_info=SimpleNamespace(goal_id=goal_uuid(goal_id), stamp=SimpleNamespace(sec=0,
                                                                                                      nanosec=0)))


def cancel_response(return_code: int, canceling: list[tuple[str, SimpleNamespace]]) -> SimpleNamespace:
    """``action_msgs/srv/CancelGoal_Response`` with the goals now canceling, ``(goal id, stamp)``."""
    return SimpleNamespace(return_code=return_code,
                           goals_canceling=[SimpleNamespace(goal_id=goal_uuid(g), stamp=s) for g, s in canceling])


def to_dict(message: Any, fields: dict[str, Any]) -> dict[str, Any]:
    """The fields of a received message that the action type knows, as plain values."""
    out: dict[str, Any] = {}
    for name in fields:
        value = getattr(message, name)
        if hasattr(value, "tolist"):
            value = value.tolist()
        elif isinstance(value, list | tuple):
            value = list(value)
        out[name] = value
    return out


def _undeclare(handle: Any) -> None:
    with contextlib.suppress(zenoh.ZError):
        handle.undeclare()


class RawPublisher:
    """Puts one ROS message type on a topic, with the ``MP`` token and attachment (reliable, blocking)."""

    def __init__(self, node: Node, name: str, typename: str, qos: Qos) -> None:
        types = ros_types()
        self._types = types
        self._typename = typename
        self._entity = node.entity("MP", name, typename, types.type_hash(typename), qos)
        options: dict[str, Any] = {"congestion_control": zenoh.CongestionControl.BLOCK,
                                   "reliability": zenoh.Reliability.RELIABLE}
        self._pub: Any
        if qos.durability == 1:
            self._pub = zenoh.ext.declare_advanced_publisher(
                node.session, self._entity.key, cache=zenoh.ext.CacheConfig(qos.depth), publisher_detection=True,
                **options)
        else:
            self._pub = node.session.declare_publisher(self._entity.key, **options)

    def put(self, message: Any) -> None:
        """Write ``message`` as CDR."""
        data = self._types.serialize(message, self._typename)
        try:
            self._pub.put(data, attachment=self._entity.attachment())
        except zenoh.ZError as exc:
            raise TransportError(f"publishing on {self._entity.key!r} failed: {exc}") from exc

    def close(self) -> None:
        """Undeclare publisher and token."""
        self._entity.close()
        _undeclare(self._pub)


class RawSubscription:
    """Calls ``on_message`` with each decoded message of one type on a topic; ``on_error`` for what does not decode."""

    def __init__(self, node: Node, name: str, typename: str, qos: Qos, on_message: Callable[[Any], None],
                 on_error: Callable[[object], None]) -> None:
        types = ros_types()
        self._types = types
        self._typename = typename
        self._on_message = on_message
        self._on_error = on_error
        self._closed = False
        self._entity = node.entity("MS", name, typename, types.type_hash(typename), qos)
        # On Zenoh's own thread (not a Python thread per subscription, zenoh-python's default): the samples of
        # one session's publishers are then handled in the order they came, across subscriptions (an action
        # client reads a goal's feedback before the status that ends it).
        handler = zenoh.handlers.Callback(self._on_sample, indirect=False)
        self._sub: Any
        if qos.durability == 1:
            history = zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=qos.depth)
            self._sub = zenoh.ext.declare_advanced_subscriber(node.session, self._entity.key, handler,
                                                              history=history)
        else:
            self._sub = node.session.declare_subscriber(self._entity.key, handler)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        if self._closed or sample.kind != zenoh.SampleKind.PUT:
            return
        try:
            attachment = sample.attachment
            decode_attachment(attachment.to_bytes() if attachment is not None else None)
            message = self._types.deserialize(sample.payload.to_bytes(), self._typename)
        except Exception as exc:
            self._on_error(exc)
            return
        self._on_message(message)

    def close(self) -> None:
        """Undeclare subscriber and token."""
        self._closed = True
        self._entity.close()
        _undeclare(self._sub)
