"""Long-running goals on Zenoh: queryables for goal, cancel and result, topics for feedback and status.

Keys, under the action name (``<base>`` is ``<ns>/<action>``; see ``docs/zenoh-wire-format.md``):

==========================================  =====================================================
``<base>/@action/goal``                     queryable: ``{"goal_id", "goal", "cancel_token"}`` ->
                                            ``{"accepted", "reason"}``
``<base>/@action/cancel``                   queryable: ``{"goal_id", "cancel_token"}`` -> ``{"accepted"}``
``<base>/@action/result``                   queryable: ``{"goal_id"}`` -> ``{"status", "result"}`` once the
                                            goal ended (the reply waits), ``{"pending": true}`` after
                                            ``wait_s`` seconds (default 1, clamped to 0..5; NaN is
                                            refused) if it still runs
``<base>/@action/feedback/<goal_id>``       samples: the feedback map
``<base>/@action/status/<goal_id>``         samples: ``{"status": <GoalStatus number>}``
``<base>/@action/result/<goal_id>``         sample: the result reply's map, once, when the goal ends
==========================================  =====================================================

Every payload is a msgpack map (``application/msgpack``). The ``@action`` chunk keeps goal
traffic out of ``<ns>/**`` topic subscriptions. A client subscribes to
``<base>/@action/*/<goal_id>`` before it sends the goal, then asks for the result in a loop of
bounded queries: a query that ends with no reply means the server is gone, and the goal ends
ABORTED with that reason. Goal and cancel queries are answered on the owner's request lane (the
server's ``accept`` is user code); result queries are held (one sweeper thread per server answers
``pending`` when their wait runs out, never a thread per query) and answered when the goal ends,
with ``"feedback_sent": n``, the number of feedback samples the goal published: feedback and
result travel on different paths, so the client waits (at most a second) for the feedback still
on its way before it reports the result.

Goal ids travel in key expressions any peer can read (``<base>/@action/status/<goal_id>``), so
knowing one must not be enough to cancel the goal: the client sends a random ``cancel_token``
with the goal, known only to it and the server, and a cancel must carry the same token. A goal
sent without a token (a client written before tokens existed) can still be cancelled by its id
alone, as before.
"""

from __future__ import annotations

import collections
import hmac
import logging
import math
import secrets
import threading
import time
from typing import Any

import zenoh

from agents_core.errors import RemoteError, RequestTimeoutError, ServiceUnavailableError, TransportError
from agents_core.transport.driver import GoalEvents, GoalServerHooks, Lane
from agents_core.transport.goal_serving import valid_goal_id
from agents_core.transport.goals import GoalStatus

from .codecs import MSGPACK, CodecError, pack, unpack
from .context import CONTROL_PRIORITY, ZenohContext, undeclare
from .queryables import read_reply

__all__ = ["ZenohActionServer", "ZenohGoal"]

logger = logging.getLogger(__name__)

#: How long one result query waits on the server before it answers ``pending`` (client asks, server caps).
RESULT_WAIT_S = 1.0
MAX_RESULT_WAIT_S = 5.0
#: Result queries a server holds at once per goal (a bound on what a peer can pile up).
MAX_HELD_QUERIES = 16
#: Goals whose feedback count a server remembers (for their result replies).
KEPT_COUNTS = 1024
#: How long a client waits, after the result, for feedback the server says it sent.
FEEDBACK_GRACE_S = 1.0
#: How long a client whose result query found no server waits for the result sample a closing server sends.
RESULT_SAMPLE_GRACE_S = 0.3
#: Length bounds of a cancel token (ours: 32 hex digits, 128 random bits).
MIN_CANCEL_TOKEN, MAX_CANCEL_TOKEN = 16, 128


def _request(query: zenoh.Query) -> dict[str, Any]:
    payload = query.payload
    if payload is None or len(payload) == 0:
        raise CodecError("the request is empty")
    doc = unpack(payload.to_bytes())
    if not isinstance(doc, dict):
        raise CodecError(f"a request must be a map, got {type(doc).__name__}")
    return doc


def _cancel_token(request: dict[str, Any], what: str) -> str | None:
    """The request's ``cancel_token`` (None when absent); CodecError for one that is not a fitting str."""
    token = request.get("cancel_token")
    if token is None:
        return None
    if not isinstance(token, str) or not MIN_CANCEL_TOKEN <= len(token) <= MAX_CANCEL_TOKEN \
            or not token.isascii():
        raise CodecError(f"a {what}'s cancel_token must be an ASCII str of {MIN_CANCEL_TOKEN} to "
                         f"{MAX_CANCEL_TOKEN} characters")
    return token


def _result_wait(wait: Any) -> float:
    """The seconds a result query may be held: ``wait_s`` clamped to 0..MAX_RESULT_WAIT_S (NaN refused).

    A NaN deadline compares false with every time, so a held query would never be answered "pending".
    """
    if isinstance(wait, bool) or not isinstance(wait, int | float):
        raise CodecError("a result request is {'goal_id': str, 'wait_s': number}")
    if math.isnan(wait):
        raise CodecError("a result request's wait_s must be a number of seconds, not NaN")
    return min(max(float(wait), 0.0), MAX_RESULT_WAIT_S)


def _answer(query: zenoh.Query, doc: dict[str, Any]) -> None:
    try:
        query.reply(query.key_expr, pack(doc), encoding=MSGPACK)
    except zenoh.ZError as exc:
        logger.debug("could not answer %s: %s", query.key_expr, exc)


def _answer_error(query: zenoh.Query, reason: str) -> None:
    try:
        query.reply_err(pack({"error": reason, "type": "CodecError"}), encoding=f"{MSGPACK};error")
    except zenoh.ZError as exc:
        logger.debug("could not send an error reply: %s", exc)


def _finalize(query: zenoh.Query) -> None:
    """End a held query: its caller stops waiting for more replies."""
    query.drop()  # type: ignore[no-untyped-call]  # zenoh's stub leaves it unannotated


class ZenohActionServer:
    """The driver side of one action server (see the module docstring)."""

    def __init__(self, context: ZenohContext, name: str, hooks: GoalServerHooks, lane: Lane) -> None:
        self.name = name
        self._context = context
        self._hooks = hooks
        self._lane = lane
        self._lock = threading.Lock()
        # Result queries waiting for their goal's end, with the time to answer "pending" instead.
        self._held: dict[str, list[tuple[zenoh.Query, float]]] = {}
        self._wake = threading.Condition(self._lock)
        # Feedback samples sent per goal, told with the result: the result travels on another
        # path than the feedback, so the client waits (bounded) for the feedback still on its way.
        self._sent: collections.OrderedDict[str, int] = collections.OrderedDict()
        # The cancel token of each goal decided or being decided (None: sent without one). Entries go
        # when the goal is rejected or finishes, so there are at most as many as goals running.
        self._tokens: dict[str, str | None] = {}
        self._closed = False
        session = context.session
        self._entities = [
            session.declare_queryable(context.goal_key(name, "goal"), self._on_goal),
            session.declare_queryable(context.goal_key(name, "cancel"), self._on_cancel),
            session.declare_queryable(context.goal_key(name, "result"), self._on_result),
        ]
        self._sweeper = threading.Thread(target=self._sweep, daemon=True, name=f"{name}:result-queries")
        self._sweeper.start()

    # -- queries ---------------------------------------------------------------------------------

    def _on_goal(self, query: zenoh.Query) -> None:
        self._lane(lambda: self._serve_goal(query))

    def _serve_goal(self, query: zenoh.Query) -> None:
        with query:
            try:
                request = _request(query)
                goal_id, goal = request.get("goal_id"), request.get("goal")
                if not isinstance(goal_id, str):
                    raise CodecError("a goal request is {'goal_id': str, 'goal': map, 'cancel_token': str}")
                token = _cancel_token(request, "goal")
            except CodecError as exc:
                self._hooks.reject(exc)
                _answer_error(query, f"the goal did not decode: {exc}")
                return
            # The token is kept before the goal is decided, so that no cancel sees the goal running
            # without it; never over the token of a goal with the same id (a peer re-sending a
            # running goal's id must not replace its token).
            with self._lock:
                owns_token = goal_id not in self._tokens
                if owns_token:
                    self._tokens[goal_id] = token
            reason = self._hooks.on_goal(goal_id, goal)
            if reason is not None and owns_token:
                with self._lock:
                    self._tokens.pop(goal_id, None)
            _answer(query, {"accepted": reason is None, "reason": reason or ""})
        if reason is None:
            self._hooks.on_accepted(goal_id)

    def _on_cancel(self, query: zenoh.Query) -> None:
        self._lane(lambda: self._serve_cancel(query))

    def _serve_cancel(self, query: zenoh.Query) -> None:
        with query:
            try:
                request = _request(query)
                goal_id = request.get("goal_id")
                if not isinstance(goal_id, str):
                    raise CodecError("a cancel request is {'goal_id': str, 'cancel_token': str}")
                token = _cancel_token(request, "cancel request")
            except CodecError as exc:
                self._hooks.reject(exc)
                _answer_error(query, f"the cancel request did not decode: {exc}")
                return
            with self._lock:
                known, required = goal_id in self._tokens, self._tokens.get(goal_id)
            if known and required is not None and (
                    token is None or not hmac.compare_digest(token.encode(), required.encode())):
                logger.info("action %r: refused a cancel of goal %s without its cancel token", self.name,
                            goal_id if valid_goal_id(goal_id) else "(invalid id)")
                _answer(query, {"accepted": False, "reason": "the cancel token does not match the goal's"})
                return
            _answer(query, {"accepted": self._hooks.on_cancel(goal_id)})

    def _on_result(self, query: zenoh.Query) -> None:
        # On Zenoh's thread: answered at once, or held until the goal ends (never a thread per query).
        try:
            request = _request(query)
            goal_id = request.get("goal_id")
            if not isinstance(goal_id, str):
                raise CodecError("a result request is {'goal_id': str, 'wait_s': number}")
            wait = _result_wait(request.get("wait_s", RESULT_WAIT_S))
        except CodecError as exc:
            self._hooks.reject(exc)
            _answer_error(query, f"the result request did not decode: {exc}")
            _finalize(query)
            return
        ended = self._hooks.wait_result(goal_id, 0.0)
        if ended is not None:
            self._reply_result(query, goal_id, ended[0], ended[1])
            return
        deadline = time.monotonic() + wait
        with self._lock:
            held = self._held.setdefault(goal_id, [])
            pending = self._closed or len(held) >= MAX_HELD_QUERIES
            if not pending:
                held.append((query, deadline))
                self._wake.notify()
            elif not held:
                del self._held[goal_id]
        if pending:
            _answer(query, {"pending": True})
            _finalize(query)
            return
        ended = self._hooks.wait_result(goal_id, 0.0)  # it may have ended while the query was being held
        if ended is not None:
            self.finish(goal_id, ended[0], ended[1])

    def _sweep(self) -> None:
        """Answer "pending" to held result queries whose wait ran out (one thread per server, not per query)."""
        while True:
            expired: list[zenoh.Query] = []
            with self._lock:
                if self._closed:
                    return
                now = time.monotonic()
                nearest = now + 1.0
                for goal_id in list(self._held):
                    keep = []
                    for query, deadline in self._held[goal_id]:
                        if deadline <= now:
                            expired.append(query)
                        else:
                            keep.append((query, deadline))
                            nearest = min(nearest, deadline)
                    if keep:
                        self._held[goal_id] = keep
                    else:
                        del self._held[goal_id]
                if not expired:
                    self._wake.wait(max(0.001, nearest - now))
            for query in expired:
                _answer(query, {"pending": True})
                _finalize(query)

    def _reply_result(self, query: zenoh.Query, goal_id: str, status: GoalStatus, result: dict[str, Any]) -> None:
        with self._lock:
            sent = self._sent.get(goal_id, 0)
        _answer(query, {"status": int(status), "result": result, "feedback_sent": sent})
        _finalize(query)

    # -- DriverActionServer ------------------------------------------------------------------------

    def feedback(self, goal_id: str, feedback: dict[str, Any]) -> None:
        """Put a feedback sample on ``<base>/@action/feedback/<goal_id>`` (see DriverActionServer)."""
        with self._lock:
            self._sent[goal_id] = self._sent.get(goal_id, 0) + 1
            self._sent.move_to_end(goal_id)
            while len(self._sent) > KEPT_COUNTS:
                self._sent.popitem(last=False)
        self._context.session.put(self._context.goal_key(self.name, "feedback", goal_id), pack(feedback),
                                  encoding=MSGPACK, priority=CONTROL_PRIORITY)

    def status(self, goal_id: str, status: GoalStatus) -> None:
        """Put a status sample on ``<base>/@action/status/<goal_id>`` (see DriverActionServer)."""
        self._context.session.put(self._context.goal_key(self.name, "status", goal_id),
                                  pack({"status": int(status)}), encoding=MSGPACK, priority=CONTROL_PRIORITY)

    def finish(self, goal_id: str, status: GoalStatus, result: dict[str, Any]) -> None:
        """Answer the goal's held result queries and put the result sample (see DriverActionServer)."""
        with self._lock:
            held = self._held.pop(goal_id, [])
            sent = self._sent.get(goal_id, 0)
            self._tokens.pop(goal_id, None)
        # Also as a sample: a client between two result queries still gets it if the server then closes.
        self._context.session.put(self._context.goal_key(self.name, "result", goal_id),
                                  pack({"status": int(status), "result": result, "feedback_sent": sent}),
                                  encoding=MSGPACK, priority=CONTROL_PRIORITY)
        for query, _deadline in held:
            self._reply_result(query, goal_id, status, result)

    def close(self) -> None:
        """Stop the sweeper, finalise the held queries and undeclare the queryables."""
        with self._lock:
            self._closed = True
            held = [q for queries in self._held.values() for q, _deadline in queries]
            self._held.clear()
            self._wake.notify_all()
        self._sweeper.join(2.0)
        for query in held:
            _finalize(query)
        for entity in reversed(self._entities):
            undeclare(entity)


class ZenohGoal:
    """A sent goal: its feedback / status subscriber and the thread that waits for its result."""

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
        self._done = threading.Event()
        self._feedback_key = context.goal_key(name, "feedback", goal_id)
        self._result_key = context.goal_key(name, "result", goal_id)
        self._result_sample = threading.Event()
        self._result_doc: dict[str, Any] = {}
        self._subscriber: Any = context.session.declare_subscriber(context.goal_key(name, "*", goal_id),
                                                                   self._on_sample)
        self._thread: threading.Thread | None = None
        self._feedback_seen = 0
        self._feedback_cond = threading.Condition()

    def _on_sample(self, sample: zenoh.Sample) -> None:
        try:
            doc = unpack(sample.payload.to_bytes())
            if not isinstance(doc, dict):
                raise CodecError(f"expected a map, got {type(doc).__name__}")
            key = str(sample.key_expr)
            if key == self._feedback_key:
                self._events.feedback(doc)
                with self._feedback_cond:
                    self._feedback_seen += 1
                    self._feedback_cond.notify_all()
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
                                            consolidation=zenoh.ConsolidationMode.NONE, priority=CONTROL_PRIORITY)
        for reply in replies:
            return read_reply(reply, f"{part} of action {self._name!r}", timeout)
        raise ServiceUnavailableError(f"nobody serves the action {self._name!r} on zenoh (key {key!r})")

    def send(self, goal: dict[str, Any], timeout: float) -> None:
        """Ask the server to take the goal; if accepted, start the thread that waits for its result."""
        started = time.monotonic()
        try:
            answer = self._query("goal", {"goal_id": self._goal_id, "goal": goal,
                                          "cancel_token": self._cancel_token}, timeout)
        except (ServiceUnavailableError, RequestTimeoutError) as exc:
            if isinstance(exc, RequestTimeoutError) or time.monotonic() - started >= timeout:
                # Accepted after its sender gave up, the goal would run for nobody: cancel it (best effort).
                self.cancel(0.5)
                raise RequestTimeoutError(f"goal to {self._name!r} got no answer within {timeout:g} s") from None
            raise
        self.accepted = answer.get("accepted") is True
        self.reason = str(answer.get("reason", ""))[:1000]
        if self.accepted:
            self._thread = threading.Thread(target=self._wait_result, daemon=True,
                                            name=f"{self._name}:result:{self._goal_id[:8]}")
            self._thread.start()

    def _wait_result(self) -> None:
        while not self._done.is_set():
            if self._result_sample.is_set():
                self._report(self._result_doc)
                return
            try:
                answer = self._query("result", {"goal_id": self._goal_id, "wait_s": RESULT_WAIT_S},
                                     RESULT_WAIT_S + 4.0)
            except (ServiceUnavailableError, RequestTimeoutError, RemoteError, TransportError, zenoh.ZError) as exc:
                # A server that closes publishes its goals' results just before its queryables go.
                if self._result_sample.wait(RESULT_SAMPLE_GRACE_S):
                    self._report(self._result_doc)
                elif not self._done.is_set():
                    self._events.finished(GoalStatus.ABORTED, {"message": f"action server {self._name!r} went "
                                                               f"away before the goal ended ({exc})"})
                return
            if answer.get("pending") is not True:
                self._report(answer)
                return

    def _report(self, answer: dict[str, Any]) -> None:
        """Hand a result reply (or result sample) to the core."""
        try:
            status = GoalStatus(int(answer.get("status", 0)))
        except (ValueError, TypeError):
            status = GoalStatus.UNKNOWN
        if status == GoalStatus.UNKNOWN:
            self._events.finished(GoalStatus.ABORTED, {"message": f"action server {self._name!r} does not "
                                                       "know the goal (restarted?)"})
            return
        self._await_feedback(answer.get("feedback_sent"))
        self._events.finished(status, answer.get("result"))

    def _await_feedback(self, sent: Any) -> None:
        """Let the feedback the server sent before the result arrive first (bounded)."""
        if isinstance(sent, bool) or not isinstance(sent, int):
            return
        deadline = time.monotonic() + FEEDBACK_GRACE_S
        with self._feedback_cond:
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
        """Stop waiting for the result and undeclare the feedback / status subscriber."""
        self._done.set()
        undeclare(self._subscriber)
