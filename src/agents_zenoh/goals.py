"""Long-running goals on Zenoh, the server side: one query stream per goal, with queryables and samples beside it.

Keys, under the action name (``<base>`` is ``<ns>/<action>``; see ``docs/zenoh-wire-format.md``):

==========================================  =====================================================
``<base>/@action/stream``                   queryable: ``{"goal_id", "goal", "cancel_token",
                                            "stream_s"}`` -> several replies on the one query:
                                            ``{"kind": "goal", "accepted", "reason"}`` (with
                                            ``"status"`` when the first status rides on it), then
                                            ``{"kind": "feedback", "feedback"}`` and
                                            ``{"kind": "status", "status"}`` while the goal runs,
                                            then ``{"kind": "result", "status", "result",
                                            "feedback_sent"}`` and the query ends
``<base>/@action/goal``                     queryable: ``{"goal_id", "goal", "cancel_token"}`` ->
                                            ``{"accepted", "reason"}`` (the two-query form)
``<base>/@action/cancel``                   queryable: ``{"goal_id", "cancel_token"}`` -> ``{"accepted"}``
``<base>/@action/result``                   queryable: ``{"goal_id"}`` -> ``{"status", "result"}`` once the
                                            goal ended (the reply waits), ``{"pending": true}`` after
                                            ``wait_s`` seconds (default 1, clamped to 0..5; NaN is
                                            refused) if it still runs
``<base>/@action/feedback/<goal_id>``       samples: the feedback map (goals with no open stream)
``<base>/@action/status/<goal_id>``         samples: ``{"status": <GoalStatus number>}``
``<base>/@action/result/<goal_id>``         sample: the result reply's map, once, when the goal ends
==========================================  =====================================================

Every payload is a msgpack map (``application/msgpack``). The ``@action`` chunk keeps goal
traffic out of ``<ns>/**`` topic subscriptions.

The stream is the fast path (one round trip: the framework's client uses it): the goal's decision,
feedback, status changes and result are replies to the one query, so they arrive in order and the
result needs no second query. An accepted goal's decision waits for its first event (EXECUTING, sent
as the goal's thread starts, right after the decision) and goes in the same reply; the terminal
status sample goes after the result reply, off the client's path. The server keeps the query while
the goal runs, until ``stream_s`` seconds (the client's query timeout, capped at an hour) after it
came; past that the goal's feedback goes out as samples again and its client follows it with result
queries. The two-query form (``goal`` then ``result`` queries, feedback as samples) stays for
clients written for it and for a client whose stream ended before the result: a result query is held
(one sweeper thread per server answers ``pending`` when its wait runs out, never a thread per query)
and answered when the goal ends, with ``"feedback_sent": n``, the number of feedback messages the
goal produced.

Goal and cancel queries (stream ones included) are decided on the lane the core gives (the server's
``accept`` is user code): one of the action server's goal threads, which then runs the goal it
accepted, or the owner's request lane while all of them are busy. A cancel is its own query on
``cancel``: it must carry the goal's ``cancel_token`` (known only to the client and the server,
since goal ids travel in key expressions any peer can read); a goal sent without a token can be
cancelled by its id alone.
"""

from __future__ import annotations

import collections
import hmac
import logging
import threading
import time
from typing import Any

import zenoh

from agents_core.transport.driver import GoalServerHooks, Lane
from agents_core.transport.goal_serving import valid_goal_id
from agents_core.transport.goals import GoalStatus

from .codecs import MSGPACK, CodecError, pack
from .context import CONTROL_PRIORITY, ZenohContext, undeclare
from .goal_wire import (
    KIND_FEEDBACK,
    KIND_GOAL,
    KIND_RESULT,
    KIND_STATUS,
    RESULT_WAIT_S,
    STREAM_S,
    answer,
    answer_error,
    cancel_token,
    finalize,
    request,
    result_wait,
    stream_seconds,
)

__all__ = ["ZenohActionServer"]

logger = logging.getLogger(__name__)

#: Result queries a server holds at once per goal (a bound on what a peer can pile up).
MAX_HELD_QUERIES = 16
#: Goals whose feedback count a server remembers (for their result replies).
KEPT_COUNTS = 1024
#: A stream is given up this long before its client's query times out (replies in flight then are lost).
STREAM_MARGIN_S = 1.0


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
        # The open stream query of each goal sent on one, with the time its client stops listening.
        self._streams: dict[str, tuple[zenoh.Query, float]] = {}
        # Held while a stream query is replied to or ended: a goal's thread and a cancel's thread
        # may reply on the same query at once, which zenoh refuses ("Already borrowed"). Taken
        # after self._lock where both are held, never the other way round.
        self._replying = threading.Lock()
        # The decision of each accepted stream goal, until its first event sends it (see _decide).
        self._undecided: dict[str, dict[str, Any]] = {}
        # Goals whose terminal status sample waits for their result reply (see status()).
        self._ending: set[str] = set()
        # Feedback messages sent per goal, told with the result: on the two-query form the result
        # travels on another path than the feedback, so the client waits (bounded) for the rest.
        self._sent: collections.OrderedDict[str, int] = collections.OrderedDict()
        # The cancel token of each goal decided or being decided (None: sent without one). Entries go
        # when the goal is rejected or finishes, so there are at most as many as goals running.
        self._tokens: dict[str, str | None] = {}
        self._closed = False
        session = context.session
        self._entities = [
            session.declare_queryable(context.goal_key(name, "stream"), self._on_stream),
            session.declare_queryable(context.goal_key(name, "goal"), self._on_goal),
            session.declare_queryable(context.goal_key(name, "cancel"), self._on_cancel),
            session.declare_queryable(context.goal_key(name, "result"), self._on_result),
        ]
        self._sweeper = threading.Thread(target=self._sweep, daemon=True, name=f"{name}:result-queries")
        self._sweeper.start()

    # -- queries ---------------------------------------------------------------------------------

    def _on_stream(self, query: zenoh.Query) -> None:
        self._lane(lambda: self._serve_goal(query, stream=True))

    def _on_goal(self, query: zenoh.Query) -> None:
        self._lane(lambda: self._serve_goal(query, stream=False))

    def _serve_goal(self, query: zenoh.Query, stream: bool) -> None:
        """Decide a goal; a stream query is kept open for the goal's feedback, status and result."""
        received = time.monotonic()
        try:
            doc = request(query)
            goal_id, goal = doc.get("goal_id"), doc.get("goal")
            if not isinstance(goal_id, str):
                raise CodecError("a goal request is {'goal_id': str, 'goal': map, 'cancel_token': str}")
            token = cancel_token(doc, "goal")
            listen_s = stream_seconds(doc.get("stream_s", STREAM_S)) if stream else 0.0
        except CodecError as exc:
            self._hooks.reject(exc)
            answer_error(query, f"the goal did not decode: {exc}")
            finalize(query)
            return
        # The token is kept before the goal is decided, so that no cancel sees the goal running
        # without it; never over the token of a goal with the same id (a peer re-sending a
        # running goal's id must not replace its token).
        with self._lock:
            owns_token = goal_id not in self._tokens
            if owns_token:
                self._tokens[goal_id] = token
        try:
            reason = self._hooks.on_goal(goal_id, goal)
        except BaseException:
            finalize(query)  # the caller stops waiting (as for every query the server does not keep)
            raise
        decision = {"accepted": reason is None, "reason": reason or ""}
        if reason is not None:
            if owns_token:
                with self._lock:
                    self._tokens.pop(goal_id, None)
            answer(query, {"kind": KIND_GOAL, **decision} if stream else decision)
            finalize(query)
            return
        if not stream:
            answer(query, decision)
            finalize(query)
        else:
            with self._lock:
                if self._closed:
                    stream = False
                else:
                    self._streams[goal_id] = (query, received + listen_s - STREAM_MARGIN_S)
                    # Sent with the goal's first event (EXECUTING, which follows at once): one reply less.
                    self._undecided[goal_id] = decision
            if not stream:
                answer(query, {"kind": KIND_GOAL, **decision})
                finalize(query)
        self._hooks.on_accepted(goal_id)
        if stream and self._hooks.wait_result(goal_id, 0.0) is not None:
            self._decide(goal_id)  # it ended (or went) before it ran: nothing else sends the decision

    def _decide(self, goal_id: str, status: GoalStatus | None = None) -> bool:
        """Send the goal's decision on its stream if it waits (with ``status`` in it); whether ``status`` went."""
        with self._lock:
            decision = self._undecided.pop(goal_id, None)
            stream = self._stream_of(goal_id) if decision is not None else None
        if stream is None or decision is None:
            return False
        if status is None:
            with self._replying:
                answer(stream, {"kind": KIND_GOAL, **decision})
            return False
        with self._replying:
            answer(stream, {"kind": KIND_GOAL, **decision, "status": int(status)})
        return True

    def _stream_of(self, goal_id: str) -> zenoh.Query | None:
        """The goal's open stream query (None when it has none or its client stopped listening); under the lock."""
        entry = self._streams.get(goal_id)
        if entry is None:
            return None
        if time.monotonic() < entry[1]:
            return entry[0]
        del self._streams[goal_id]
        with self._replying:
            finalize(entry[0])
        return None

    def _on_cancel(self, query: zenoh.Query) -> None:
        self._lane(lambda: self._serve_cancel(query))

    def _serve_cancel(self, query: zenoh.Query) -> None:
        with query:
            try:
                doc = request(query)
                goal_id = doc.get("goal_id")
                if not isinstance(goal_id, str):
                    raise CodecError("a cancel request is {'goal_id': str, 'cancel_token': str}")
                token = cancel_token(doc, "cancel request")
            except CodecError as exc:
                self._hooks.reject(exc)
                answer_error(query, f"the cancel request did not decode: {exc}")
                return
            with self._lock:
                known, required = goal_id in self._tokens, self._tokens.get(goal_id)
            if known and required is not None and (
                    token is None or not hmac.compare_digest(token.encode(), required.encode())):
                logger.info("action %r: refused a cancel of goal %s without its cancel token", self.name,
                            goal_id if valid_goal_id(goal_id) else "(invalid id)")
                answer(query, {"accepted": False, "reason": "the cancel token does not match the goal's"})
                return
            answer(query, {"accepted": self._hooks.on_cancel(goal_id)})

    def _on_result(self, query: zenoh.Query) -> None:
        # On Zenoh's thread: answered at once, or held until the goal ends (never a thread per query).
        try:
            doc = request(query)
            goal_id = doc.get("goal_id")
            if not isinstance(goal_id, str):
                raise CodecError("a result request is {'goal_id': str, 'wait_s': number}")
            wait = result_wait(doc.get("wait_s", RESULT_WAIT_S))
        except CodecError as exc:
            self._hooks.reject(exc)
            answer_error(query, f"the result request did not decode: {exc}")
            finalize(query)
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
            answer(query, {"pending": True})
            finalize(query)
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
                answer(query, {"pending": True})
                finalize(query)

    def _reply_result(self, query: zenoh.Query, goal_id: str, status: GoalStatus, result: dict[str, Any]) -> None:
        with self._lock:
            sent = self._sent.get(goal_id, 0)
        answer(query, {"status": int(status), "result": result, "feedback_sent": sent})
        finalize(query)

    # -- DriverActionServer ------------------------------------------------------------------------

    def feedback(self, goal_id: str, feedback: dict[str, Any]) -> None:
        """Send a feedback map on the goal's stream, or as a sample on ``<base>/@action/feedback/<goal_id>``."""
        if self._undecided:
            self._decide(goal_id)
        with self._lock:
            self._sent[goal_id] = self._sent.get(goal_id, 0) + 1
            self._sent.move_to_end(goal_id)
            while len(self._sent) > KEPT_COUNTS:
                self._sent.popitem(last=False)
            stream = self._stream_of(goal_id)
        if stream is not None:
            with self._replying:
                answer(stream, {"kind": KIND_FEEDBACK, "feedback": feedback})
            return
        self._context.session.put(self._context.goal_key(self.name, "feedback", goal_id), pack(feedback),
                                  encoding=MSGPACK, priority=CONTROL_PRIORITY)

    def status(self, goal_id: str, status: GoalStatus) -> None:
        """Put a status sample on ``<base>/@action/status/<goal_id>`` (and on the goal's stream, if open)."""
        if status.is_terminal:
            with self._lock:
                if self._stream_of(goal_id) is not None:
                    # The result reply carries it: the sample goes after it (finish), off the client's path.
                    self._ending.add(goal_id)
                    return
        elif not (self._undecided and self._decide(goal_id, status)):
            with self._lock:
                stream = self._stream_of(goal_id)
            if stream is not None:
                with self._replying:
                    answer(stream, {"kind": KIND_STATUS, "status": int(status)})
        # Also as a sample: peers watch ``status/*`` (the goal's own client reads its stream).
        self._put_status(goal_id, status)

    def _put_status(self, goal_id: str, status: GoalStatus) -> None:
        self._context.session.put(self._context.goal_key(self.name, "status", goal_id),
                                  pack({"status": int(status)}), encoding=MSGPACK, priority=CONTROL_PRIORITY)

    def finish(self, goal_id: str, status: GoalStatus, result: dict[str, Any]) -> None:
        """End the goal's stream with its result, answer its held result queries and put the result sample."""
        if self._undecided:
            self._decide(goal_id)
        with self._lock:
            deferred = goal_id in self._ending
            self._ending.discard(goal_id)
            held = self._held.pop(goal_id, [])
            sent = self._sent.get(goal_id, 0)
            self._tokens.pop(goal_id, None)
            stream = self._stream_of(goal_id)
            self._streams.pop(goal_id, None)
        doc = {"status": int(status), "result": result, "feedback_sent": sent}
        if deferred and stream is None:  # its stream ended meanwhile: the samples go in their usual order
            self._put_status(goal_id, status)
        if stream is not None:
            with self._replying:
                answer(stream, {"kind": KIND_RESULT, **doc}, express=True)
                finalize(stream)
            if deferred:
                self._put_status(goal_id, status)
        else:
            # As a sample: a client between two result queries still gets it if the server then closes.
            self._context.session.put(self._context.goal_key(self.name, "result", goal_id), pack(doc),
                                      encoding=MSGPACK, priority=CONTROL_PRIORITY)
        for query, _deadline in held:
            self._reply_result(query, goal_id, status, result)

    def close(self) -> None:
        """Stop the sweeper, finalise the held queries and open streams and undeclare the queryables.

        The core ends running goals (:meth:`finish`) before it closes the driver side, so a stream
        still open here belongs to a goal that could not be ended: its client sees the stream end
        without a result and follows up with a result query.
        """
        with self._lock:
            self._closed = True
            held = [q for queries in self._held.values() for q, _deadline in queries]
            held += [q for q, _deadline in self._streams.values()]
            self._held.clear()
            self._streams.clear()
            self._undecided.clear()
            self._ending.clear()
            self._wake.notify_all()
        self._sweeper.join(2.0)
        for query in held:
            with self._replying:
                finalize(query)
        for entity in reversed(self._entities):
            undeclare(entity)
