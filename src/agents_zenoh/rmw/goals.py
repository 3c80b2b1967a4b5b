"""Long-running goals on rmw_zenoh: a ROS 2 action server and a goal client, as rcl_action speaks them.

The names and types are in :mod:`.actions`. The server (:class:`RmwActionServer`):

- ``send_goal``: the goal is decoded and handed to the core (``hooks.on_goal``, on the server's lane,
  since it may run the ``accept`` callback); an accepted goal is listed in the status array
  (ACCEPTED), answered, then started (``hooks.on_accepted``);
- ``cancel_goal``: the core decides (``hooks.on_cancel``); a zero goal id cancels every running
  goal (as in rcl_action); the return code is NONE, REJECTED, UNKNOWN_GOAL_ID or GOAL_TERMINATED;
- ``get_result``: answered at once for an ended goal, else kept and answered when the goal ends
  (the query's reply is sent from the goal's thread);
- feedback and status changes are published on the two topics; a terminal status other than
  SUCCEEDED, CANCELED or ABORTED travels as ABORTED.

The client side is one :class:`RmwActionClient` per action (its feedback and status subscriptions,
declared before the first goal is sent, shared by the goals sent to it, as rclpy's ``ActionClient``)
and one :class:`RmwGoal` per goal, which follows the goal with ``get_result`` queries of
:data:`RESULT_QUERY_S` each; one that finds no server (its token gone) ends the goal ABORTED with
that reason. A running goal keeps at most :data:`MAX_WAITING` result queries.
"""

from __future__ import annotations

import collections
import logging
import threading
import time
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any, Protocol

from agents_core.errors import RequestTimeoutError, ServiceUnavailableError, TransportError
from agents_core.transport.driver import GoalEvents, GoalServerHooks, Lane
from agents_core.transport.goals import ActionType, GoalStatus

from .actions import (
    CANCEL_GOAL,
    FEEDBACK_QOS,
    STATUS_ARRAY,
    STATUS_QOS,
    ActionNames,
    RawPublisher,
    RawSubscription,
    cancel_request,
    cancel_response,
    feedback_message,
    result_request,
    result_response,
    send_goal_request,
    send_goal_response,
    stamp_now,
    status_array,
    to_dict,
    uuid_hex,
)
from .entities import Node, ServiceServer

__all__ = ["RESULT_QUERY_S", "ActionDriver", "RmwActionClient", "RmwActionServer", "RmwGoal"]

logger = logging.getLogger(__name__)

#: How long one get_result query of a client waits (it asks again while the server is there).
RESULT_QUERY_S = 2.0
#: Ended goals kept in the status array.
KEPT_STATUSES = 32
#: Results kept for get_result queries that come after the end.
KEPT_RESULTS = 256
#: Result queries kept per running goal (older ones are dropped unanswered: their clients have timed out).
MAX_WAITING = 16
#: After the result, how long a client waits for feedback that may still be on its way (it travels on a topic).
FEEDBACK_SETTLE_S = 0.05
_WIRE_TERMINAL = (GoalStatus.SUCCEEDED, GoalStatus.CANCELED, GoalStatus.ABORTED)
#: action_msgs/srv/CancelGoal return codes.
CANCEL_NONE, CANCEL_REJECTED, CANCEL_UNKNOWN, CANCEL_TERMINATED = 0, 1, 2, 3
_ZERO_ID = "0" * 32

Answer = Callable[[Any], None]


class ActionDriver(Protocol):
    """What goals need of :class:`~agents_zenoh.rmw.transport.RmwZenohDriver`."""

    def node_for(self, owner: str | None) -> Node:
        """The node of component ``owner``, or the transport's own."""
        ...

    def ros_request(self, name: str, service_type: str, request: Any, timeout: float) -> Any:
        """Call a ROS service; the response message."""
        ...

    def served(self, name: str, service_type: str) -> bool:
        """Whether a server of the service is seen."""
        ...


class RmwActionServer:
    """The driver side of one action server on a component's node (see the module docstring)."""

    def __init__(self, driver: ActionDriver, name: str, definition: ActionType, hooks: GoalServerHooks,
                 owner: str | None, lane: Lane) -> None:
        self.name = name
        self._definition = definition
        self._hooks = hooks
        self._lane = lane
        self._names = names = ActionNames(name, definition)
        self._lock = threading.Lock()
        #: goal id -> [stamp, wire status], oldest first (the status array).
        self._goals: collections.OrderedDict[str, list[Any]] = collections.OrderedDict()
        self._results: collections.OrderedDict[str, tuple[int, dict[str, Any]]] = collections.OrderedDict()
        self._waiting: dict[str, list[Answer]] = {}
        node = driver.node_for(owner)
        self._feedback = RawPublisher(node, names.feedback, names.feedback_type, FEEDBACK_QOS)
        self._status = RawPublisher(node, names.status, STATUS_ARRAY, STATUS_QOS)
        self._servers = [
            ServiceServer(node, names.send_goal, names.send_goal_type, self._on_send_goal, hooks.reject),
            ServiceServer(node, names.cancel_goal, CANCEL_GOAL, self._on_cancel, hooks.reject),
            ServiceServer(node, names.get_result, names.get_result_type, self._on_get_result, hooks.reject)]

    # -- the three services (Zenoh's threads) -----------------------------------------------------

    def _on_send_goal(self, request: Any, answer: Answer) -> None:
        stamp = stamp_now()
        try:
            goal_id = uuid_hex(request.goal_id)
            goal = to_dict(request.goal, self._definition.goal)
        except Exception as exc:
            self._hooks.reject(f"send_goal: {exc}")
            answer(send_goal_response(False, stamp))
            return

        def decide() -> None:
            reason = self._hooks.on_goal(goal_id, goal)
            if reason is not None:
                answer(send_goal_response(False, stamp))
                return
            with self._lock:
                self._goals[goal_id] = [stamp, int(GoalStatus.ACCEPTED)]
            self._publish_status()
            answer(send_goal_response(True, stamp))
            self._hooks.on_accepted(goal_id)

        self._lane(decide)

    def _on_cancel(self, request: Any, answer: Answer) -> None:
        code, infos = CANCEL_UNKNOWN, []
        try:
            goal_id = uuid_hex(request.goal_info.goal_id)
            with self._lock:
                running = [g for g, (_s, status) in self._goals.items() if status not in _WIRE_TERMINAL]
                ended = goal_id in self._results
            targets = running if goal_id == _ZERO_ID else [g for g in running if g == goal_id]
            canceling = [g for g in targets if self._hooks.on_cancel(g)]
            with self._lock:
                infos = [(g, self._goals[g][0]) for g in canceling if g in self._goals]
            if canceling:
                code = CANCEL_NONE
            elif targets:
                code = CANCEL_REJECTED
            elif ended:
                code = CANCEL_TERMINATED
        finally:
            answer(cancel_response(code, infos))

    def _on_get_result(self, request: Any, answer: Answer) -> None:
        try:
            goal_id = uuid_hex(request.goal_id)
        except TransportError as exc:
            self._hooks.reject(f"get_result: {exc}")
            answer(None)
            return
        stale: list[Answer] = []
        with self._lock:
            done = self._results.get(goal_id)
            kept = done is None and goal_id in self._goals
            if kept:
                waiting = self._waiting.setdefault(goal_id, [])
                waiting.append(answer)
                # A client asks again when its query times out: the oldest queries are the given-up ones.
                stale, waiting[:] = waiting[:-MAX_WAITING], waiting[-MAX_WAITING:]
        for old in stale:
            old(None)
        if kept:
            return  # answered by finish()
        if done is None:
            found = self._hooks.wait_result(goal_id, 0.0)
            done = (int(found[0]), found[1]) if found is not None and found[0] in _WIRE_TERMINAL else None
        if done is None:
            answer(self._result_response(int(GoalStatus.UNKNOWN), {}))
            return
        answer(self._result_response(*done))

    def _result_response(self, status: int, result: dict[str, Any]) -> SimpleNamespace:
        return result_response(status, {**self._definition.defaults("result"), **result})

    def _publish_status(self) -> None:
        with self._lock:
            entries = [(g, stamp, status) for g, (stamp, status) in self._goals.items()]
        try:
            self._status.put(status_array(entries))
        except TransportError as exc:
            self._hooks.reject(f"status of {self.name!r} not published: {exc}")

    # -- DriverActionServer (the goal's thread) -----------------------------------------------------

    def feedback(self, goal_id: str, feedback: dict[str, Any]) -> None:
        self._feedback.put(feedback_message(goal_id, {**self._definition.defaults("feedback"), **feedback}))

    def status(self, goal_id: str, status: GoalStatus) -> None:
        if status.is_terminal:
            return  # finish() sets and publishes it with the result
        with self._lock:
            entry = self._goals.get(goal_id)
            if entry is None:
                return
            entry[1] = int(status)
        self._publish_status()

    def finish(self, goal_id: str, status: GoalStatus, result: dict[str, Any]) -> None:
        wire = int(status) if status in _WIRE_TERMINAL else int(GoalStatus.ABORTED)
        with self._lock:
            self._results[goal_id] = (wire, dict(result))
            while len(self._results) > KEPT_RESULTS:
                self._results.popitem(last=False)
            entry = self._goals.get(goal_id)
            if entry is not None:
                entry[1] = wire
            ended = [g for g, (_s, st) in self._goals.items() if st in _WIRE_TERMINAL]
            for old in ended[:max(0, len(ended) - KEPT_STATUSES)]:
                del self._goals[old]
            waiting = self._waiting.pop(goal_id, [])
        self._publish_status()
        response = self._result_response(wire, result)
        for answer in waiting:
            answer(response)

    def close(self) -> None:
        for server in self._servers:
            server.close()
        with self._lock:
            waiting = [a for answers in self._waiting.values() for a in answers]
            self._waiting.clear()
        for answer in waiting:
            answer(None)  # no reply: the client's query ends, and it sees the server gone
        self._feedback.close()
        self._status.close()

    def __repr__(self) -> str:
        return f"<RmwActionServer {self.name!r} {self._definition.ros_type}>"


class RmwActionClient:
    """The client side of one action (name and type): the feedback and status subscriptions its goals share.

    Samples are handed to the goal they name; samples of goals sent by others are skipped, and what does
    not decode is counted in :attr:`decode_errors`.
    """

    def __init__(self, driver: ActionDriver, name: str, definition: ActionType) -> None:
        self.name = name
        self.definition = definition
        self.names = names = ActionNames(name, definition)
        self.decode_errors = 0
        self._lock = threading.Lock()
        self._goals: dict[str, RmwGoal] = {}
        node = driver.node_for(None)
        self._subs = [
            RawSubscription(node, names.feedback, names.feedback_type, FEEDBACK_QOS, self._on_feedback, self._reject),
            RawSubscription(node, names.status, STATUS_ARRAY, STATUS_QOS, self._on_status, self._reject)]

    def add(self, goal: RmwGoal) -> None:
        """Hand ``goal`` its feedback and status from now on."""
        with self._lock:
            self._goals[goal.goal_id] = goal

    def remove(self, goal: RmwGoal) -> None:
        """Stop handing ``goal`` anything."""
        with self._lock:
            if self._goals.get(goal.goal_id) is goal:
                del self._goals[goal.goal_id]

    def _goal(self, uuid_msg: Any) -> RmwGoal | None:
        goal_id = uuid_hex(uuid_msg)
        with self._lock:
            return self._goals.get(goal_id)

    def _reject(self, reason: object) -> None:
        self.decode_errors += 1
        logger.debug("action %r: a feedback or status sample did not decode: %s", self.name, reason)

    def _on_feedback(self, message: Any) -> None:
        try:
            goal = self._goal(message.goal_id)
        except TransportError as exc:
            self._reject(exc)
            return
        if goal is not None:
            goal.on_feedback(message.feedback)

    def _on_status(self, message: Any) -> None:
        for entry in message.status_list:
            try:
                goal = self._goal(entry.goal_info.goal_id)
            except TransportError as exc:
                self._reject(exc)
                continue
            if goal is not None:
                goal.on_status(int(entry.status))

    def close(self) -> None:
        """Undeclare the subscriptions."""
        for sub in self._subs:
            sub.close()


class RmwGoal:
    """A sent goal (see the module docstring)."""

    def __init__(self, driver: ActionDriver, client: RmwActionClient, goal_id: str, events: GoalEvents) -> None:
        self.accepted = False
        self.reason = ""
        self.goal_id = goal_id
        self._driver = driver
        self._client = client
        self._name = client.name
        self._definition = client.definition
        self._goal_id = goal_id
        self._events = events
        self._names = client.names
        self._done = threading.Event()
        #: The status array listed this goal as ended: the server published it after its last feedback.
        self._ended = threading.Event()
        self._last_feedback = 0.0
        self._last_status = -1
        client.add(self)

    def on_feedback(self, feedback_msg: Any) -> None:
        """Feedback for this goal arrived (Zenoh's thread)."""
        try:
            feedback = to_dict(feedback_msg, self._definition.feedback)
        except Exception as exc:
            self._events.reject(exc)
            return
        self._last_feedback = time.monotonic()
        self._events.feedback(feedback)

    def on_status(self, status: int) -> None:
        """The status array listed this goal with ``status`` (Zenoh's thread)."""
        if status in _WIRE_TERMINAL:
            self._ended.set()
        if status != self._last_status and status in (GoalStatus.EXECUTING, GoalStatus.CANCELING):
            self._last_status = status
            self._events.status(GoalStatus(status))

    def send(self, goal: dict[str, Any], timeout: float) -> None:
        """Send the goal and wait for the server's decision; then follow it on a thread of its own."""
        names = self._names
        request = send_goal_request(self._goal_id, goal)
        try:
            response = self._driver.ros_request(names.send_goal, names.send_goal_type, request, timeout)
        except RequestTimeoutError:
            if not self._driver.served(names.send_goal, names.send_goal_type):
                raise ServiceUnavailableError(f"no action server {self._name!r} on rmw_zenoh") from None
            raise
        except ServiceUnavailableError:
            raise ServiceUnavailableError(f"no action server {self._name!r} on rmw_zenoh") from None
        self.accepted = bool(response.accepted)
        if not self.accepted:
            self.reason = f"action server {self._name!r} did not accept the goal"
            return
        threading.Thread(target=self._follow, daemon=True, name=f"{self._name}:result:{self._goal_id[:8]}").start()

    def _follow(self) -> None:
        names = self._names
        request = result_request(self._goal_id)
        while not self._done.is_set():
            try:
                response = self._driver.ros_request(names.get_result, names.get_result_type, request, RESULT_QUERY_S)
            except RequestTimeoutError:
                continue  # still running
            except ServiceUnavailableError:
                self._events.finished(GoalStatus.ABORTED, {"message": f"action server {self._name!r} went away "
                                                           "before the goal ended"})
                return
            except TransportError as exc:
                if not self._done.is_set():
                    self._events.finished(GoalStatus.ABORTED, {"message": f"goal on {self._name!r}: {exc}"})
                return
            self._deliver(response)
            return

    def _deliver(self, response: Any) -> None:
        status = int(response.status)
        if status not in _WIRE_TERMINAL:
            self._events.finished(GoalStatus.ABORTED, {"message": f"action server {self._name!r} does not know "
                                                       f"the goal (status {status})"})
            return
        try:
            result = to_dict(response.result, self._definition.result)
        except Exception as exc:
            self._events.reject(exc)
            result = {}
        # Feedback travels on a topic, the result as a reply: let feedback still on its way arrive first. The
        # server publishes the ended goal's status after its last feedback, on the same session (reliable, in
        # order): once that is here, so is the feedback. A server that publishes no status (it need not): wait
        # until no feedback came for FEEDBACK_SETTLE_S, bounded.
        settle_until = time.monotonic() + 6 * FEEDBACK_SETTLE_S
        while not self._ended.is_set() and time.monotonic() - self._last_feedback < FEEDBACK_SETTLE_S \
                and time.monotonic() < settle_until:
            self._ended.wait(FEEDBACK_SETTLE_S / 5)
        self._events.finished(GoalStatus(status), result)

    def cancel(self, timeout: float) -> bool:
        """Ask the server to cancel the goal; whether it is now canceling."""
        names = self._names
        request = cancel_request(self._goal_id)
        try:
            response = self._driver.ros_request(names.cancel_goal, CANCEL_GOAL, request, timeout)
        except (RequestTimeoutError, ServiceUnavailableError):
            return False
        canceling = []
        for info in response.goals_canceling:
            try:
                canceling.append(uuid_hex(info.goal_id))
            except TransportError as exc:
                self._events.reject(exc)
        return self._goal_id in canceling

    def close(self) -> None:
        """Stop following the goal."""
        self._done.set()
        self._client.remove(self)
