"""The goal bookkeeping, once for every driver: action servers and sent goals.

:class:`CoreActionServer` is what ``transport.create_action_server`` returns. It gets goals,
cancels and result requests from the driver (it is the driver's
:class:`~agents_core.transport.driver.GoalServerHooks`) and keeps:

- validation of each goal against its :class:`~agents_core.transport.goals.ActionType` (a
  goal that does not fit is rejected with the reason, and counted), goal ids (a duplicate id is
  rejected), a bound on goals running at once, and the server's ``accept`` callback;
- one thread per running goal, named after the action, running the execute callback (never
  the middleware's thread, never a component's step worker); threads are reused from goal to goal
  (:mod:`~agents_core.transport.goal_threads`);
- the status of each goal (ACCEPTED -> EXECUTING -> CANCELING -> terminal), sent through the
  driver, and the terminal result, kept for a while for result requests that come late;
- the closed state: closing the server aborts the goals still running, with the reason in the
  result's ``message``, so that a client never waits for a result that cannot come.

:func:`send_goal` is the client side: goal validation, a fresh goal id, the result and the
feedback (on a bounded thread of the goal's own), and the result's validation.
"""

from __future__ import annotations

import collections
import logging
import re
import threading
import time
import uuid
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from attrs import define

from ..errors import ComponentError, TypeValidationError
from ..support.concurrency import CloseOnce
from ..telemetry import switch as _telemetry
from .goal_threads import ReusedThreads
from .goals import ActionType, GoalClient, GoalHandle, GoalStatus, inline_feedback, refuse_in_inline_feedback

if TYPE_CHECKING:
    from .driver import DriverActionServer, DriverGoal, Lane, TransportDriver

__all__ = [
    "ActionServerStatistics",
    "CoreActionServer",
    "GoalAccept",
    "GoalExecute",
    "abort_locally",
    "new_goal_id",
    "send_goal",
    "valid_goal_id",
]

logger = logging.getLogger(__name__)

#: The execute callback of an action server: runs one goal, returns its result dict.
GoalExecute = Callable[[GoalHandle], dict[str, Any]]
#: Decides whether a validated goal is accepted.
GoalAccept = Callable[[dict[str, Any]], bool]

#: Goals one server runs at once at most (a bound on threads a network peer can make us start).
MAX_RUNNING_GOALS = 32
#: Results of ended goals kept for result requests that come after the end.
KEPT_RESULTS = 256
#: Longest goal id accepted from the network: exactly 32 lowercase hex digits (a UUID, as ROS 2 has it).
MAX_GOAL_ID_LENGTH = 32
#: A goal id as the wire documents it. ASCII only: ``str.isalnum``/``isdigit`` would also take
#: Unicode letters and digits ("٣", "é"), which then end up in Zenoh keys and logs.
_GOAL_ID = re.compile(r"[0-9a-f]{32}")
#: How long closing a server waits for the threads of the goals it aborted to return.
CLOSE_JOIN_S = 1.0
#: Feedback messages waiting for a slow feedback callback before the oldest is dropped.
FEEDBACK_QUEUE_DEPTH = 64


@define
class ActionServerStatistics:
    """Counters of one action server."""

    accepted: int = 0
    rejected: int = 0
    succeeded: int = 0
    canceled: int = 0
    aborted: int = 0
    #: Goals, cancels or result requests from the network that did not decode.
    decode_errors: int = 0
    running: int = 0


def valid_goal_id(goal_id: Any) -> bool:
    """Whether ``goal_id`` (from the network) is 32 lowercase ASCII hex digits, as every goal id must be."""
    return isinstance(goal_id, str) and _GOAL_ID.fullmatch(goal_id) is not None


class CoreActionServer:
    """An action server: the driver carries goals, this class runs them (see the module docstring)."""

    def __init__(self, name: str, definition: ActionType, execute: GoalExecute, accept: GoalAccept | None,
                 owner: str | None, on_close: Callable[[CoreActionServer], None]) -> None:
        if not callable(execute):
            raise ComponentError(f"action server {name!r}: execute must be callable, got {execute!r}")
        if accept is not None and not callable(accept):
            raise ComponentError(f"action server {name!r}: accept must be callable or None, got {accept!r}")
        self.name = name
        self.action_type = definition
        self.owner = owner
        self._execute = execute
        self._accept = accept
        self._on_close = on_close
        self._driver_server: DriverActionServer | None = None
        self._lock = threading.Condition()
        self._running: dict[str, GoalHandle] = {}
        self._threads: dict[str, threading.Thread] = {}
        self._ended: collections.OrderedDict[str, tuple[GoalStatus, dict[str, Any]]] = collections.OrderedDict()
        # Cancels that came before their goal was decided (its sender gave up waiting): such a goal
        # is refused when it is decided. Bounded, as the ids come from the network.
        self._early_cancels: collections.OrderedDict[str, None] = collections.OrderedDict()
        self._stats = ActionServerStatistics()
        self._close_once = CloseOnce()
        # Each running goal has a thread to itself; a thread whose goal ended waits a while for the
        # next goal rather than ending (starting one costs more than a short goal's round trip).
        self._workers = ReusedThreads(f"{name}:goal-idle")

    # -- GoalServerHooks (called by the driver) ---------------------------------------------------

    def on_goal(self, goal_id: str, goal: Any) -> str | None:
        """Validate and decide on a goal; None if accepted, else the reason (see GoalServerHooks)."""
        reason = self._decide(goal_id, goal)
        with self._lock:
            if reason is None:
                self._stats.accepted += 1
            else:
                self._stats.rejected += 1
        if reason is not None:
            logger.info("action %r rejected a goal: %s", self.name, reason)
        return reason

    def _decide(self, goal_id: str, goal: Any) -> str | None:
        if not valid_goal_id(goal_id):
            return f"invalid goal id {str(goal_id)[:80]!r} (expected 32 lowercase hex digits)"
        try:
            checked = self.action_type.validate("goal", goal)
        except TypeValidationError as exc:
            return str(exc)
        with self._lock:
            if self._close_once.closed:
                return f"action server {self.name!r} is closed"
            if goal_id in self._running or goal_id in self._ended:
                return f"goal id {goal_id} is already in use"
            if goal_id in self._early_cancels:
                return f"goal {goal_id} was cancelled before it was accepted"
            if len(self._running) >= MAX_RUNNING_GOALS:
                return f"action server {self.name!r} already runs {MAX_RUNNING_GOALS} goals"
        if self._accept is not None:
            try:
                if not self._accept(checked):
                    return f"action server {self.name!r} did not accept the goal"
            except Exception as exc:
                return f"action server {self.name!r}: accept raised {type(exc).__name__}: {exc}"
        handle = GoalHandle(goal_id, checked, self.action_type, self._send_feedback, self._cancel_requested)
        with self._lock:
            if self.closed:  # closed while accept() ran
                return f"action server {self.name!r} is closed"
            if goal_id in self._running:
                return f"goal id {goal_id} is already in use"
            if self._early_cancels.pop(goal_id, 0) is None:  # cancelled while accept() ran
                return f"goal {goal_id} was cancelled before it was accepted"
            self._running[goal_id] = handle
        return None

    def on_accepted(self, goal_id: str) -> None:
        """Start the goal on a thread of its own (an idle one of this server's, or a new one)."""
        with self._lock:
            handle = self._running.get(goal_id)
            if handle is None or goal_id in self._threads:
                return
            name = f"{self.name}:goal:{goal_id[:8]}"
            # Decided on one of this server's threads (see lane()): the goal runs on it next.
            thread = self._workers.then(lambda: self._run(handle), name)
            try:
                self._threads[goal_id] = thread or self._workers.run(lambda: self._run(handle), name)
            except RuntimeError:  # closed meanwhile: close() aborts the goal
                return

    def on_cancel(self, goal_id: str) -> bool:
        """Mark a running goal canceling; False for a goal that has ended or is unknown."""
        if not valid_goal_id(goal_id):
            return False
        with self._lock:
            handle = self._running.get(goal_id)
            if handle is None and goal_id not in self._ended:
                self._early_cancels[goal_id] = None
                while len(self._early_cancels) > KEPT_RESULTS:
                    self._early_cancels.popitem(last=False)
        if handle is None:
            return False
        handle.request_cancel()
        return True

    def wait_result(self, goal_id: str, timeout: float) -> tuple[GoalStatus, dict[str, Any]] | None:
        """The ended goal's status and result, None if it still runs after ``timeout`` (see GoalServerHooks)."""
        deadline = time.monotonic() + max(0.0, timeout)
        with self._lock:
            while True:
                ended = self._ended.get(goal_id)
                if ended is not None:
                    return ended[0], dict(ended[1])
                if goal_id not in self._running:
                    return GoalStatus.UNKNOWN, {}
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._lock.wait(left)

    def lane(self, fallback: Lane) -> Lane:
        """Where the driver runs this server's goal and cancel requests: on one of its goal threads.

        A goal accepted there then runs on the same thread (no hand-off, see :meth:`on_accepted`).
        The accept callback is user code, so it never runs on the middleware's thread either way.
        While :data:`MAX_RUNNING_GOALS` threads are busy (goals, or a peer's flood of requests),
        requests queue on ``fallback`` (the owner's request lane) instead of starting more threads.
        """
        def submit(job: Callable[[], None]) -> None:
            if self._workers.busy < MAX_RUNNING_GOALS:
                try:
                    self._workers.run(job, f"{self.name}:goal-request")
                    return
                except RuntimeError:  # closed: the owner's lane drops it as it drops every late request
                    pass
            fallback(job)

        return submit

    def reject(self, reason: object) -> None:
        """Count a request from the network that did not decode."""
        with self._lock:
            self._stats.decode_errors += 1
            first = self._stats.decode_errors == 1
        (logger.warning if first else logger.debug)("action %r: a request did not decode: %s", self.name, reason)

    # -- running goals ----------------------------------------------------------------------------

    def _driver(self) -> DriverActionServer | None:
        return self._driver_server

    def attach(self, driver_server: DriverActionServer) -> None:
        """Carry goal events through ``driver_server`` (what the driver's ``serve_goals`` returned)."""
        self._driver_server = driver_server

    def _send_feedback(self, handle: GoalHandle, feedback: dict[str, Any]) -> None:
        driver = self._driver()
        if driver is not None and handle.goal_id in self._running:
            driver.feedback(handle.goal_id, feedback)

    def _cancel_requested(self, handle: GoalHandle) -> None:
        driver = self._driver()
        if driver is not None and handle.goal_id in self._running:
            driver.status(handle.goal_id, GoalStatus.CANCELING)

    def _run(self, handle: GoalHandle) -> None:
        tel = _telemetry.hooks
        if tel is None:
            self._run_goal(handle)
            return
        with tel.call("goal", self.name, {"agents.goal_id": handle.goal_id}):
            self._run_goal(handle)

    def _run_goal(self, handle: GoalHandle) -> None:
        driver = self._driver()
        if driver is not None and not handle.cancel_requested:
            driver.status(handle.goal_id, GoalStatus.EXECUTING)
        try:
            returned = self._execute(handle)
            status = handle.outcome or (GoalStatus.CANCELED if handle.cancel_requested else GoalStatus.SUCCEEDED)
            result = self.action_type.validate("result", {} if returned is None else returned)
            if status == GoalStatus.ABORTED and handle._abort_reason:
                self._explain(result, handle._abort_reason)
        except TypeValidationError as exc:
            status, result = GoalStatus.ABORTED, self._aborted(f"invalid result: {exc}")
        except Exception as exc:
            logger.warning("action %r: goal %s raised %s: %s", self.name, handle.goal_id, type(exc).__name__, exc)
            status, result = GoalStatus.ABORTED, self._aborted(f"{type(exc).__name__}: {exc}")
        self._complete(handle, status, result)

    def _explain(self, result: dict[str, Any], reason: str) -> None:
        if "message" in self.action_type.result and self.action_type.result["message"].kind == "str" \
                and not result.get("message"):
            result["message"] = reason

    def _aborted(self, reason: str) -> dict[str, Any]:
        result = self.action_type.defaults("result")
        self._explain(result, reason)
        return result

    def _complete(self, handle: GoalHandle, status: GoalStatus, result: dict[str, Any]) -> bool:
        """Record the goal's end once and hand it to the driver; False if it had ended already."""
        handle._end()
        with self._lock:
            if self._running.pop(handle.goal_id, None) is None:
                return False
            self._threads.pop(handle.goal_id, None)
            self._ended[handle.goal_id] = (status, result)
            while len(self._ended) > KEPT_RESULTS:
                self._ended.popitem(last=False)
            field = {GoalStatus.SUCCEEDED: "succeeded", GoalStatus.CANCELED: "canceled"}.get(status, "aborted")
            setattr(self._stats, field, getattr(self._stats, field) + 1)
            self._lock.notify_all()
        driver = self._driver()
        if driver is not None:
            try:
                driver.status(handle.goal_id, status)
                driver.finish(handle.goal_id, status, result)
            except Exception as exc:  # the middleware went away: the client learns it from its side
                logger.debug("action %r: the result of goal %s was not sent: %s", self.name, handle.goal_id, exc)
        return True

    # -- public -----------------------------------------------------------------------------------

    def statistics(self) -> ActionServerStatistics:
        """A snapshot of the server's counters."""
        with self._lock:
            s = self._stats
            return ActionServerStatistics(accepted=s.accepted, rejected=s.rejected, succeeded=s.succeeded,
                                          canceled=s.canceled, aborted=s.aborted, decode_errors=s.decode_errors,
                                          running=len(self._running))

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` ran."""
        return self._close_once.closed

    def close(self) -> None:
        """Abort the goals still running (reason in the result), then stop serving; idempotent."""
        if not self._close_once.claim():
            return
        # Taken after the claim: a goal decided meanwhile either sees the server closed or is here.
        with self._lock:
            running = list(self._running.values())
            threads = list(self._threads.values())
        reason = f"action server {self.name!r} closed while the goal ran"
        for handle in running:
            # Ended first, then woken: the execute callback, seeing the cancel, must not get to
            # report its own outcome before the abort.
            self._complete(handle, GoalStatus.ABORTED, self._aborted(reason))
            handle._cancel.set()
        self._workers.close()
        self._on_close(self)
        driver, self._driver_server = self._driver_server, None
        if driver is not None:
            try:
                driver.close()
            except Exception as exc:
                logger.debug("closing action server %r: %s", self.name, exc)
        deadline = time.monotonic() + CLOSE_JOIN_S
        for thread in threads:
            if thread is not threading.current_thread():
                thread.join(max(0.0, deadline - time.monotonic()))

    def __repr__(self) -> str:
        return f"<CoreActionServer {self.name!r} {self.action_type.name} running={len(self._running)}>"


#: The threads that call feedback callbacks: each goal's feedback runs on one at a time, in order.
_FEEDBACK_THREADS = ReusedThreads("goal-feedback-idle")


class _FeedbackDelivery:
    """Calls a goal's feedback callback off the middleware's thread, behind a bounded queue (drop oldest).

    While feedback waits, one thread (borrowed from :data:`_FEEDBACK_THREADS`, named
    ``goal-feedback:<id>``) calls the callback with each message in order; it goes back when the
    queue is empty, so a goal holds no thread between bursts and none is started to send it.
    Drops are counted in the client's ``feedback_dropped``.
    """

    def __init__(self, client: GoalClient, callback: Callable[[dict[str, Any]], None], inline: bool = False) -> None:
        self._client = client
        self._callback = callback
        # Called on the caller's thread (the driver's), no queue: see Transport.send_goal's feedback_inline.
        self._inline = inline
        self._lock = threading.Lock()
        self._items: collections.deque[dict[str, Any]] = collections.deque()
        self._draining = False
        self._stopped = False
        self._name = f"goal-feedback:{client.goal_id[:8]}"

    def offer(self, feedback: dict[str, Any]) -> None:
        """Queue ``feedback`` (never blocks); the oldest waiting one goes when the queue is full."""
        if self._inline:
            if not self._stopped:
                self._call(feedback)
            return
        with self._lock:
            if self._stopped:
                return
            dropped = len(self._items) >= FEEDBACK_QUEUE_DEPTH
            if dropped:
                self._items.popleft()
            self._items.append(feedback)
            start = not self._draining
            self._draining = True
        if dropped:
            self._client.feedback_dropped += 1
        if start:
            _FEEDBACK_THREADS.run(self._drain, self._name)

    def _drain(self) -> None:
        while True:
            with self._lock:
                if not self._items:
                    self._draining = False
                    return
                item = self._items.popleft()
            self._call(item)

    def _call(self, item: dict[str, Any]) -> None:
        try:
            if self._inline:
                with inline_feedback():  # calls that wait refuse to run here (refuse_in_inline_feedback)
                    self._callback(item)
            else:
                self._callback(item)
        except Exception as exc:
            logger.warning("feedback callback of goal %s raised %s: %s", self._client.goal_id,
                           type(exc).__name__, exc)

    def stop(self, *, discard: bool = False) -> int:
        """No more feedback comes: what waits is still delivered (or, ``discard=True``, dropped); returns
        how many were discarded."""
        with self._lock:
            self._stopped = True
            count = len(self._items) if discard else 0
            if discard:
                self._items.clear()
        return count


class _ClientEvents:
    """The core's :class:`~agents_core.transport.driver.GoalEvents` for one sent goal."""

    def __init__(self, client: GoalClient, delivery: _FeedbackDelivery | None) -> None:
        self._client = client
        self._delivery = delivery

    def feedback(self, feedback: Any) -> None:
        client = self._client
        if client.done:
            return
        try:
            checked = client.action_type.validate("feedback", feedback)
        except Exception as exc:
            self.reject(f"feedback: {exc}")
            return
        client.feedback_received += 1
        if self._delivery is not None:
            self._delivery.offer(checked)

    def status(self, status: GoalStatus) -> None:
        try:
            self._client._set_status(GoalStatus(status))
        except ValueError:
            self.reject(f"unknown goal status {status!r}")

    def finished(self, status: GoalStatus, result: Any) -> None:
        client = self._client
        try:
            status = GoalStatus(status)
            if not status.is_terminal:
                raise TypeValidationError(f"status {status.name} is not terminal")
            checked = client.action_type.validate("result", result)
        except (TypeValidationError, ValueError) as exc:
            self.reject(f"result: {exc}")
            status, checked = GoalStatus.ABORTED, client.action_type.defaults("result")
            if "message" in checked:
                checked["message"] = f"the result did not decode: {exc}"
        client._finish(status, checked)

    def reject(self, reason: object) -> None:
        self._client.feedback_errors += 1
        logger.debug("goal %s on %r: %s", self._client.goal_id, self._client.action_name, reason)

    def stop(self) -> None:
        if self._delivery is not None:
            self._delivery.stop()


def new_goal_id() -> str:
    """A fresh goal id: 32 hex digits (a UUID4, as ROS 2 uses)."""
    return uuid.uuid4().hex


def send_goal(driver: TransportDriver, name: str, definition: ActionType, goal: Any,
              feedback: Callable[[dict[str, Any]], None] | None, timeout: float,
              on_done: Callable[[GoalClient], None], inline: bool = False) -> tuple[GoalClient, DriverGoal]:
    """Validate ``goal``, send it through ``driver`` and wait for its acceptance (see ``Transport.send_goal``).

    ``feedback`` runs on a thread of the goal's own, behind a bounded queue (a slow callback never
    holds up the result). With ``inline`` it runs on the thread that hands the driver's events in
    (Zenoh's, the ROS 2 executor's, the server's goal thread on memory) with no hand-off: for a
    callback that returns at once, as the goal's later feedback and its result wait behind it. That
    thread is the one that brings answers in, so a call that waits for one (``goal.cancel()``,
    ``goal.result()``, ``send_goal``, ``request``) raises ComponentError from such a callback
    (:func:`~agents_core.transport.goals.refuse_in_inline_feedback`); ``goal.cancel_async()`` cancels
    without waiting.

    A rejected goal comes back finished with :attr:`GoalStatus.REJECTED` and the reason in the
    result's ``message`` (when the type has one).
    """
    refuse_in_inline_feedback("transport.send_goal()")
    checked = definition.validate("goal", goal)
    if feedback is not None and not callable(feedback):
        raise ComponentError(f"send_goal to {name!r}: feedback must be callable or None, got {feedback!r}")
    client = GoalClient(new_goal_id(), name, definition)
    delivery = _FeedbackDelivery(client, feedback, inline) if feedback is not None else None
    events = _ClientEvents(client, delivery)
    client._when_done(events.stop)
    try:
        handle = driver.send_goal(name, definition, client.goal_id, checked, events, timeout)
    except BaseException:
        events.stop()
        raise
    client._when_done(handle.close)
    client._when_done(lambda: on_done(client))
    if handle.accepted:
        client._accepted(handle.cancel)
    else:
        result = definition.defaults("result")
        if "message" in result:
            result["message"] = handle.reason or f"{name!r} rejected the goal"
        client._finish(GoalStatus.REJECTED, result)
    return client, handle


def abort_locally(client: GoalClient, reason: str) -> None:
    """End a sent goal here as ABORTED (its transport closed); the server is not told."""
    result = client.action_type.defaults("result")
    if "message" in result:
        result["message"] = reason
    client._finish(GoalStatus.ABORTED, result)
