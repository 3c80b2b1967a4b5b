"""Long-running goals on Zenoh, the client side: one query stream per goal, result queries when it ends early.

A goal is one query on ``<base>/@action/stream`` (see :mod:`agents_zenoh.goals` and
``docs/zenoh-wire-format.md``): the first reply is the server's decision, the next ones the goal's
feedback and status, the last one its result. Replies to one query arrive in order, so the result
never overtakes feedback and one round trip carries the whole goal. The replies are read on
Zenoh's thread with no waiting: they are handed to the core's :class:`GoalEvents`.

When the stream ends without a result (the server went away, closed, or the goal outlived the
stream's hour) a thread follows the goal the two-query way: it subscribes to the goal's samples
and asks ``result`` in a loop of bounded queries; a result query with no reply means the server
is gone, and the goal ends ABORTED with that reason. A stream query that nobody answers at all
is retried as a ``goal`` query, so a server that predates streams is still reached.
"""

from __future__ import annotations

import secrets
import threading
import time
from typing import Any

import zenoh

from agents_core.errors import RemoteError, RequestTimeoutError, ServiceUnavailableError, TransportError
from agents_core.transport.driver import GoalEvents
from agents_core.transport.goals import GoalStatus

from .codecs import MSGPACK, CodecError, pack, unpack
from .context import CONTROL_PRIORITY, ZenohContext, undeclare
from .goal_wire import KIND_FEEDBACK, KIND_GOAL, KIND_RESULT, KIND_STATUS, RESULT_WAIT_S, STREAM_S
from .queryables import read_reply

__all__ = ["ZenohGoal"]

#: How long a client waits, after a result from a result query, for feedback the server says it sent.
FEEDBACK_GRACE_S = 1.0
#: How long a client whose result query found no server waits for the result sample a closing server sends.
RESULT_SAMPLE_GRACE_S = 0.3
#: Longest reason kept from a rejection.
MAX_REASON = 1000


class ZenohGoal:
    """A sent goal: its stream query, and the subscriber and thread that follow it if the stream ends early."""

    def __init__(self, context: ZenohContext, name: str, goal_id: str, events: GoalEvents) -> None:
        self.accepted = False
        self.reason = ""
        self._context = context
        self._name = name
        self._goal_id = goal_id
        # Known only to this client and the server: a peer that reads the goal's status keys (and so
        # its id) cannot cancel it without this.
        self._cancel_token = secrets.token_hex(16)
        self._events = events
        self._lock = threading.Lock()
        self._done = threading.Event()
        self._finished = False
        # The stream's first reply (or its end): the decision, or why there is none.
        self._answered = threading.Event()
        self._decision: dict[str, Any] | None = None
        self._failure: Exception | None = None
        self._feedback_key = context.goal_key(name, "feedback", goal_id)
        self._result_key = context.goal_key(name, "result", goal_id)
        self._result_sample = threading.Event()
        self._result_doc: dict[str, Any] = {}
        self._subscriber: Any = None
        self._thread: threading.Thread | None = None
        self._feedback_seen = 0
        self._feedback_awaited = False
        self._feedback_cond = threading.Condition()

    # -- sending ---------------------------------------------------------------------------------

    def send(self, goal: dict[str, Any], timeout: float) -> None:
        """Send the goal on a stream query and wait (at most ``timeout``) for the server's decision."""
        started = time.monotonic()
        request = {"goal_id": self._goal_id, "goal": goal, "cancel_token": self._cancel_token, "stream_s": STREAM_S}
        # indirect=False: the replies are read on Zenoh's thread (they never wait there), not on a
        # Python thread zenoh-python would start for this query (a thread start per goal).
        self._context.session.get(self._context.goal_key(self._name, "stream"),
                                  zenoh.handlers.Callback(self._on_reply, self._on_stream_end, indirect=False),
                                  payload=pack(request), encoding=MSGPACK, timeout=STREAM_S,
                                  consolidation=zenoh.ConsolidationMode.NONE, priority=CONTROL_PRIORITY,
                                  express=True)
        if not self._answered.wait(timeout):
            self._gave_up(timeout)
        if self._failure is not None:
            raise self._failure
        decision = self._decision
        if decision is None:  # the stream ended unanswered: nobody serves it, or a server from before streams
            self._send_two_queries(goal, max(0.0, timeout - (time.monotonic() - started)), started, timeout)
            return
        self.accepted = decision.get("accepted") is True
        self.reason = str(decision.get("reason", ""))[:MAX_REASON]

    def _gave_up(self, timeout: float) -> None:
        """No decision in time: a goal accepted after its sender gave up would run for nobody, so cancel it."""
        self._done.set()
        self.cancel(0.5)
        raise RequestTimeoutError(f"goal to {self._name!r} got no answer within {timeout:g} s")

    def _send_two_queries(self, goal: dict[str, Any], left: float, started: float, timeout: float) -> None:
        """The goal as a ``goal`` query, followed by samples and result queries (servers without streams)."""
        self._subscribe()
        try:
            answer = self._query("goal", {"goal_id": self._goal_id, "goal": goal,
                                          "cancel_token": self._cancel_token}, left)
        except (ServiceUnavailableError, RequestTimeoutError) as exc:
            if isinstance(exc, RequestTimeoutError) or time.monotonic() - started >= timeout:
                self._gave_up(timeout)
            raise
        self.accepted = answer.get("accepted") is True
        self.reason = str(answer.get("reason", ""))[:MAX_REASON]
        if self.accepted:
            self._start_follower()

    # -- the stream (on Zenoh's thread: never waits) ---------------------------------------------

    def _on_reply(self, reply: zenoh.Reply) -> None:
        what = f"goal stream of action {self._name!r}"
        try:
            doc = read_reply(reply, what, STREAM_S)
        except (RemoteError, RequestTimeoutError) as exc:
            if not self._answered.is_set():
                self._failure = exc
                self._answered.set()
            elif not isinstance(exc, RequestTimeoutError):  # the stream's hour is up: its end is handled
                self._events.reject(exc)
            return
        kind = doc.get("kind")
        if not self._answered.is_set():
            if kind != KIND_GOAL:
                self._failure = RemoteError(f"{what} began with a {str(kind)[:40]!r} reply, not the decision")
            else:
                self._decision = doc
                if "status" in doc:  # the goal's first status (EXECUTING) rides on its decision
                    try:
                        self._events.status(GoalStatus(doc["status"]))
                    except (ValueError, TypeError) as exc:
                        self._events.reject(exc)
            self._answered.set()
            return
        if self._done.is_set():
            return
        try:
            if kind == KIND_FEEDBACK:
                feedback = doc.get("feedback")
                if not isinstance(feedback, dict):
                    raise CodecError(f"feedback must be a map, got {type(feedback).__name__}")
                self._events.feedback(feedback)
                self._count_feedback()
            elif kind == KIND_STATUS:
                self._events.status(GoalStatus(doc["status"]))
            elif kind == KIND_RESULT:
                self._report(doc, wait_feedback=False)  # in order on the stream: the feedback is all in
            else:
                raise CodecError(f"unknown goal stream reply kind {str(kind)[:40]!r}")
        except (CodecError, KeyError, ValueError, TypeError) as exc:
            self._events.reject(exc)

    def _on_stream_end(self) -> None:
        self._answered.set()  # a stream that ends unanswered: send() falls back to a goal query
        decision = self._decision
        with self._lock:
            follow = not self._finished and decision is not None and decision.get("accepted") is True
        if follow and not self._done.is_set():
            self._start_follower()

    # -- following a goal without its stream -----------------------------------------------------

    def _subscribe(self) -> None:
        with self._lock:
            if self._subscriber is None and not self._done.is_set():
                self._subscriber = self._context.session.declare_subscriber(
                    self._context.goal_key(self._name, "*", self._goal_id), self._on_sample)

    def _start_follower(self) -> None:
        with self._lock:
            if self._thread is not None:
                return
            self._thread = threading.Thread(target=self._follow, daemon=True,
                                            name=f"{self._name}:result:{self._goal_id[:8]}")
        self._thread.start()

    def _on_sample(self, sample: zenoh.Sample) -> None:
        try:
            doc = unpack(sample.payload.to_bytes())
            if not isinstance(doc, dict):
                raise CodecError(f"expected a map, got {type(doc).__name__}")
            key = str(sample.key_expr)
            if key == self._feedback_key:
                self._events.feedback(doc)
                self._count_feedback()
            elif key == self._result_key:
                self._result_doc = doc  # the result thread reports it (Zenoh's thread must not wait)
                self._result_sample.set()
            else:
                self._events.status(GoalStatus(doc["status"]))
        except (CodecError, KeyError, ValueError, TypeError) as exc:
            self._events.reject(exc)

    def _query(self, part: str, request: dict[str, Any], timeout: float) -> dict[str, Any]:
        key = self._context.goal_key(self._name, part)
        replies = self._context.session.get(key, payload=pack(request), encoding=MSGPACK, timeout=timeout,
                                            consolidation=zenoh.ConsolidationMode.NONE, priority=CONTROL_PRIORITY,
                                  express=True)
        for reply in replies:
            return read_reply(reply, f"{part} of action {self._name!r}", timeout)
        raise ServiceUnavailableError(f"nobody serves the action {self._name!r} on zenoh (key {key!r})")

    def _follow(self) -> None:
        """Ask for the result in a loop of bounded queries (the goal's samples bring its feedback)."""
        self._subscribe()
        while not self._done.is_set() and not self._finished:
            if self._result_sample.is_set():
                self._report(self._result_doc, wait_feedback=True)
                return
            try:
                answer = self._query("result", {"goal_id": self._goal_id, "wait_s": RESULT_WAIT_S},
                                     RESULT_WAIT_S + 4.0)
            except (ServiceUnavailableError, RequestTimeoutError, RemoteError, TransportError, zenoh.ZError) as exc:
                # A server that closes publishes its goals' results just before its queryables go.
                if self._result_sample.wait(RESULT_SAMPLE_GRACE_S):
                    self._report(self._result_doc, wait_feedback=True)
                elif not self._done.is_set():
                    self._finish(GoalStatus.ABORTED, {"message": f"action server {self._name!r} went "
                                                      f"away before the goal ended ({exc})"})
                return
            if answer.get("pending") is not True:
                self._report(answer, wait_feedback=True)
                return

    # -- the end ---------------------------------------------------------------------------------

    def _report(self, answer: dict[str, Any], wait_feedback: bool) -> None:
        """Hand a result (stream reply, result reply or result sample) to the core."""
        try:
            status = GoalStatus(int(answer.get("status", 0)))
        except (ValueError, TypeError):
            status = GoalStatus.UNKNOWN
        if status == GoalStatus.UNKNOWN:
            self._finish(GoalStatus.ABORTED, {"message": f"action server {self._name!r} does not "
                                              "know the goal (restarted?)"})
            return
        if wait_feedback:
            self._await_feedback(answer.get("feedback_sent"))
        self._finish(status, answer.get("result"))

    def _finish(self, status: GoalStatus, result: Any) -> None:
        """Report the goal's end once, whichever path (stream, result query, sample) brought it first."""
        with self._lock:
            if self._finished:
                return
            self._finished = True
        self._events.finished(status, result)

    def _count_feedback(self) -> None:
        # The condition is taken only while a result waits for feedback (see _await_feedback): the
        # waiter sets the flag under it before it reads the count, so no increment goes unseen.
        self._feedback_seen += 1
        if self._feedback_awaited:
            with self._feedback_cond:
                self._feedback_cond.notify_all()

    def _await_feedback(self, sent: Any) -> None:
        """Let the feedback the server sent before the result arrive first (bounded)."""
        if isinstance(sent, bool) or not isinstance(sent, int):
            return
        deadline = time.monotonic() + FEEDBACK_GRACE_S
        with self._feedback_cond:
            self._feedback_awaited = True
            while self._feedback_seen < sent and not self._done.is_set():
                left = deadline - time.monotonic()
                if left <= 0:
                    return
                self._feedback_cond.wait(left)

    def cancel(self, timeout: float) -> bool:
        """Ask the server to cancel the goal; False when it refuses or does not answer (see DriverGoal)."""
        try:
            request = {"goal_id": self._goal_id, "cancel_token": self._cancel_token}
            return self._query("cancel", request, timeout).get("accepted") is True
        except (ServiceUnavailableError, RemoteError, RequestTimeoutError):
            return False

    def close(self) -> None:
        """Stop following the goal: later replies are ignored, the samples' subscriber is undeclared."""
        self._done.set()
        with self._lock:
            subscriber, self._subscriber = self._subscriber, None
        if subscriber is not None:
            undeclare(subscriber)
