"""Long-running goals on ROS 2: a real rclpy ``ActionServer`` / ``ActionClient`` per action.

A served action is a plain ROS 2 action of the type's ``ros_type`` (for the built-in
``VisionLanguageAction``: ``agents_interfaces/action/VisionLanguageAction``) on the owner's node,
so ``rclpy.action.ActionClient`` and any ROS 2 tool can send goals, read feedback, cancel and
get results. The mapping onto rclpy:

- rclpy's goal callback asks the core (``hooks.on_goal``) and answers ACCEPT / REJECT; the
  accepted-goal callback keeps rclpy's goal handle and starts the goal's thread (the core's);
- the goal's thread marks it executing (``goal_handle.execute()``, which here schedules nothing
  on the executor), publishes feedback and, at the end, sets the terminal state and hands the
  result to rclpy through a callback that returns at once, so the executor thread never runs
  (or waits for) a goal;
- rclpy's cancel callback asks the core (``hooks.on_cancel``).

A sent goal uses an ``ActionClient`` (kept per action, as service clients are). Its result is
awaited on a thread of the goal's own, which also watches the server: a server that disappears
for :data:`SERVER_GONE_S` ends the goal ABORTED with that reason.
"""

from __future__ import annotations

import importlib
import logging
import threading
import time
from typing import TYPE_CHECKING, Any

from rclpy.action import ActionClient, ActionServer, CancelResponse, GoalResponse
from unique_identifier_msgs.msg import UUID

from agents_core.errors import RequestTimeoutError, ServiceUnavailableError, TransportError
from agents_core.transport.driver import GoalEvents, GoalServerHooks
from agents_core.transport.goals import ActionType, GoalStatus

if TYPE_CHECKING:
    from rclpy.node import Node

__all__ = ["Ros2ActionServer", "Ros2Goal", "ros_action_class"]

logger = logging.getLogger(__name__)

#: A sent goal whose server has not been seen for this long ends ABORTED.
SERVER_GONE_S = 2.0
#: How long closing a server waits for rclpy to take the results of the goals it ended.
CLOSE_FLUSH_S = 1.0
_POLL_S = 0.05


def ros_action_class(definition: ActionType) -> Any:
    """The rclpy action class of ``definition.ros_type`` (``pkg/action/Name``); TransportError if missing."""
    parts = definition.ros_type.split("/")
    if len(parts) != 3 or parts[1] != "action":
        raise TransportError(f"action type {definition.name!r} has no ROS 2 type (ros_type "
                             f"{definition.ros_type!r}; expected 'package/action/Name')")
    try:
        return getattr(importlib.import_module(f"{parts[0]}.action"), parts[2])
    except (ImportError, AttributeError) as exc:
        raise TransportError(f"the ROS 2 action type {definition.ros_type!r} is not installed: {exc}") from exc


def _to_dict(message: Any, fields: dict[str, Any]) -> dict[str, Any]:
    """The fields of a ROS message that the action type knows, as plain values."""
    out: dict[str, Any] = {}
    for name in fields:
        value = getattr(message, name)
        out[name] = list(value) if not isinstance(value, str | bytes | bool | int | float) else value
    return out


def _to_message(cls: Any, value: dict[str, Any]) -> Any:
    message = cls()
    for name, item in value.items():
        setattr(message, name, item)
    return message


def _goal_id(uuid_msg: Any) -> str:
    return bytes(uuid_msg.uuid).hex()


class _ThreadedActionServer(ActionServer):  # type: ignore[misc]  # rclpy is untyped
    """rclpy's action server, except that ``goal_handle.execute()`` only marks the goal executing.

    The goal runs on the core's thread; :meth:`deliver` hands its result to rclpy.
    """

    #: The id of the goal request being decided: rclpy gives the goal callback the goal only.
    incoming_goal_id = ""

    async def _execute_goal_request(self, request_header_and_message: Any) -> None:
        # The goal callback runs synchronously inside this coroutine on the executor thread,
        # so the id read here is the one of the goal it decides on.
        self.incoming_goal_id = _goal_id(request_header_and_message[1].goal_id)
        await super()._execute_goal_request(request_header_and_message)

    def notify_execute(self, goal_handle: Any, execute_callback: Any) -> None:
        if execute_callback is not None:
            super().notify_execute(goal_handle, execute_callback)


class Ros2ActionServer:
    """The driver side of one action server on ``node`` (see the module docstring)."""

    def __init__(self, node: Node, name: str, definition: ActionType, hooks: GoalServerHooks,
                 absolute: str) -> None:
        self.name = name
        self._definition = definition
        self._hooks = hooks
        self._node = node
        self._cls = ros_action_class(definition)
        self._lock = threading.Lock()
        self._handles: dict[str, Any] = {}
        self._flushed: list[threading.Event] = []
        self._closed = False
        self._server = _ThreadedActionServer(
            node, self._cls, absolute, execute_callback=self._never_called, goal_callback=self._on_goal,
            handle_accepted_callback=self._on_accepted, cancel_callback=self._on_cancel)

    @staticmethod
    def _never_called(goal_handle: Any) -> Any:
        raise RuntimeError("goals run on the core's threads")

    # -- rclpy callbacks (executor thread) ---------------------------------------------------------

    def _on_goal(self, goal_request: Any) -> GoalResponse:
        goal_id = self._server.incoming_goal_id
        try:
            goal = _to_dict(goal_request, self._definition.goal)
        except Exception as exc:
            self._hooks.reject(exc)
            return GoalResponse.REJECT
        reason = self._hooks.on_goal(goal_id, goal)
        return GoalResponse.ACCEPT if reason is None else GoalResponse.REJECT

    def _on_accepted(self, goal_handle: Any) -> None:
        goal_id = _goal_id(goal_handle.goal_id)
        with self._lock:
            self._handles[goal_id] = goal_handle
        self._hooks.on_accepted(goal_id)

    def _on_cancel(self, goal_handle: Any) -> CancelResponse:
        accepted = self._hooks.on_cancel(_goal_id(goal_handle.goal_id))
        return CancelResponse.ACCEPT if accepted else CancelResponse.REJECT

    # -- DriverActionServer (the goal's thread) -----------------------------------------------------

    def _handle(self, goal_id: str) -> Any:
        with self._lock:
            return self._handles.get(goal_id)

    def feedback(self, goal_id: str, feedback: dict[str, Any]) -> None:
        handle = self._handle(goal_id)
        if handle is not None:
            handle.publish_feedback(_to_message(self._cls.Feedback, feedback))

    def status(self, goal_id: str, status: GoalStatus) -> None:
        # CANCELING is set by rclpy when it accepts a cancel; terminal states are set in finish().
        handle = self._handle(goal_id)
        if handle is not None and status == GoalStatus.EXECUTING:
            try:
                handle.execute()
            except Exception as exc:  # a cancel got there first: the transition is not allowed
                logger.debug("goal %s: not marked executing: %s", goal_id, exc)

    def finish(self, goal_id: str, status: GoalStatus, result: dict[str, Any]) -> None:
        with self._lock:
            handle = self._handles.pop(goal_id, None)
        if handle is None:
            return
        try:
            if status == GoalStatus.SUCCEEDED:
                handle.succeed()
            elif status == GoalStatus.CANCELED and handle.is_cancel_requested:
                handle.canceled()
            else:  # ABORTED, or CANCELED by server-side preemption, which ROS 2 can only show as aborted
                handle.abort()
        except Exception as exc:
            logger.debug("goal %s: terminal state not set (%s); aborting", goal_id, exc)
            if handle.is_active:
                handle.abort()
        message = _to_message(self._cls.Result, result)
        flushed = threading.Event()
        with self._lock:
            self._flushed = [e for e in self._flushed if not e.is_set()] + [flushed]

        def deliver(_goal_handle: Any) -> Any:
            flushed.set()
            return message

        # Runs on the executor: rclpy's own step that stores the result and answers result requests.
        self._server.notify_execute(handle, deliver)

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            waiting = list(self._flushed)
        deadline = time.monotonic() + CLOSE_FLUSH_S
        for event in waiting:
            event.wait(max(0.0, deadline - time.monotonic()))
        if waiting:
            # rclpy answers pending result requests in a task of its own right after the result is
            # stored: give it a moment, so clients that asked get the result before the server goes.
            time.sleep(0.05)
        try:
            self._server.destroy()
        except Exception as exc:
            logger.debug("destroying the action server %r: %s", self.name, exc)


class Ros2Goal:
    """A sent goal on an rclpy ``ActionClient`` (see the module docstring)."""

    def __init__(self, client: ActionClient, name: str, definition: ActionType, goal_id: str,
                 events: GoalEvents) -> None:
        self.accepted = False
        self.reason = ""
        self._client = client
        self._name = name
        self._definition = definition
        self._goal_id = goal_id
        self._events = events
        self._cls = client._action_type
        self._handle: Any = None
        self._done = threading.Event()

    def _on_feedback(self, message: Any) -> None:
        try:
            self._events.feedback(_to_dict(message.feedback, self._definition.feedback))
        except Exception as exc:
            self._events.reject(exc)

    def send(self, goal: dict[str, Any], timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while not self._client.server_is_ready():
            if time.monotonic() >= deadline:
                raise ServiceUnavailableError(f"no action server {self._name!r} appeared within {timeout:g} s")
            time.sleep(0.02)
        uuid_msg = UUID(uuid=list(bytes.fromhex(self._goal_id)))
        future = self._client.send_goal_async(_to_message(self._cls.Goal, goal), feedback_callback=self._on_feedback,
                                              goal_uuid=uuid_msg)
        try:
            self._handle = _wait(future, deadline, f"goal to {self._name!r}", cancel=False)
        except RequestTimeoutError:
            # Accepted after its sender gave up, the goal would run for nobody: cancel it then.
            future.add_done_callback(_cancel_if_accepted)
            raise
        self.accepted = bool(self._handle.accepted)
        if not self.accepted:
            self.reason = f"action server {self._name!r} did not accept the goal"
            return
        threading.Thread(target=self._wait_result, daemon=True, name=f"{self._name}:result:{self._goal_id[:8]}").start()

    def _wait_result(self) -> None:
        future = self._handle.get_result_async()
        done = threading.Event()
        future.add_done_callback(lambda _f: done.set())
        last_status = None
        unseen_since: float | None = None
        while not done.wait(_POLL_S):
            if self._done.is_set():
                return
            status = self._handle.status
            if status != last_status and status in (GoalStatus.EXECUTING, GoalStatus.CANCELING):
                last_status = status
                self._events.status(GoalStatus(status))
            if self._client.server_is_ready():
                unseen_since = None
            elif unseen_since is None:
                unseen_since = time.monotonic()
            elif time.monotonic() - unseen_since > SERVER_GONE_S:
                self._events.finished(GoalStatus.ABORTED, {"message": f"action server {self._name!r} went away "
                                                           "before the goal ended"})
                return
        response = future.result()
        try:
            result = _to_dict(response.result, self._definition.result)
        except Exception as exc:
            self._events.reject(exc)
            result = {}
        status = GoalStatus(response.status) if response.status in GoalStatus._value2member_map_ else \
            GoalStatus.ABORTED
        self._events.finished(status, result)

    def cancel(self, timeout: float) -> bool:
        if self._handle is None:
            return False
        try:
            response = _wait(self._handle.cancel_goal_async(), time.monotonic() + timeout,
                             f"cancel of a goal on {self._name!r}")
        except RequestTimeoutError:
            return False
        return len(response.goals_canceling) > 0

    def close(self) -> None:
        self._done.set()


def _wait(future: Any, deadline: float, what: str, *, cancel: bool = True) -> Any:
    done = threading.Event()
    future.add_done_callback(lambda _f: done.set())
    if not done.wait(max(0.0, deadline - time.monotonic())):
        if cancel:
            future.cancel()
        raise RequestTimeoutError(f"{what} got no answer in time")
    return future.result()


def _cancel_if_accepted(future: Any) -> None:
    try:
        handle = future.result()
        if handle is not None and handle.accepted:
            handle.cancel_goal_async()
    except Exception as exc:  # the transport closed meanwhile
        logger.debug("cancelling a goal accepted after its sender gave up: %s", exc)
