"""Request/reply and component presence of the Zenoh driver, on queryables and liveliness tokens.

A handler never runs on a Zenoh thread: queries for services and transitions go to the owner's
request lane (given by the core), and each query is finalised (dropped) when answered, so the
caller never waits for more than the reply. Only the state query, which just reads a snapshot,
is answered on Zenoh's thread.
"""

from __future__ import annotations

import json
import logging
import threading
from typing import Any

import zenoh

from agents_core.errors import RemoteError, RequestTimeoutError
from agents_core.messages import ComponentStatusMsg
from agents_core.status import HealthStatus, LifecycleState
from agents_core.support import bounded_json
from agents_core.supported_types import ComponentStatus
from agents_core.transport.contract import ServiceHandler, TransitionHandler
from agents_core.transport.driver import Lane
from agents_core.transport.requests import serve_with_caller_deadline

from .codecs import DEFAULT_DECODE_LIMITS, MSGPACK, CodecError, codec_for, encode_value, pack, unpack
from .codecs.limits import json_limits
from .context import ZenohContext, undeclare
from .keys import liveliness_key, state_key, transition_key

__all__ = ["ERROR_ENCODING", "ZenohPresence", "ZenohService", "read_reply"]

logger = logging.getLogger(__name__)

#: Encoding of an error reply: a msgpack map ``{"error": "<Type>: <message>", "type": "<Type>"}``.
ERROR_ENCODING = f"{MSGPACK};error"
_JSON_ENCODINGS = ("application/json", "text/json")
# A request sent as JSON is bounded like its msgpack form (DEFAULT_DECODE_LIMITS, what unpack() uses).
_REQUEST_JSON_LIMITS = json_limits(DEFAULT_DECODE_LIMITS)


def _wants_json(query: zenoh.Query) -> bool:
    """Whether ``query`` came as JSON, and so is answered (errors included) as JSON."""
    encoding = str(query.encoding) if query.encoding is not None else ""
    return encoding.startswith(_JSON_ENCODINGS)


def _read_request(query: zenoh.Query, as_json: bool) -> dict[str, Any]:
    """The request map of ``query``, decoded under the request limits; raises :class:`CodecError`."""
    payload = query.payload
    if payload is None or len(payload) == 0:
        return {}
    if as_json:
        if len(payload) > _REQUEST_JSON_LIMITS.max_bytes:  # before copying it out of Zenoh's buffer
            raise CodecError(f"the JSON request has {len(payload)} bytes, more than "
                             f"{_REQUEST_JSON_LIMITS.max_bytes} (DecodeLimits.max_document_bytes)")
        try:
            doc = bounded_json.loads(payload.to_bytes(), _REQUEST_JSON_LIMITS)
        except bounded_json.InvalidJsonError as exc:
            # The same error type as a msgpack request that does not decode, whatever the encoding.
            raise CodecError(str(exc)) from exc
    else:
        doc = unpack(payload.to_bytes())
    if not isinstance(doc, dict):
        raise CodecError(f"a request must be a map, got {type(doc).__name__}")
    return doc


def _reply(query: zenoh.Query, key: str, result: dict[str, Any], as_json: bool) -> None:
    if as_json:
        query.reply(key, json.dumps(result).encode(), encoding="application/json")
    else:
        query.reply(key, pack(result), encoding=MSGPACK)


def _reply_error(query: zenoh.Query, exc: BaseException, as_json: bool) -> None:
    body = {"error": f"{type(exc).__name__}: {exc}", "type": type(exc).__name__}
    try:
        if as_json:
            query.reply_err(json.dumps(body).encode(), encoding="application/json;error")
        else:
            query.reply_err(pack(body), encoding=ERROR_ENCODING)
    except zenoh.ZError as err:
        logger.debug("could not send an error reply: %s", err)


class ZenohService:
    """A queryable on ``<namespace>/<service>`` whose queries run ``handler`` on the owner's lane."""

    def __init__(self, context: ZenohContext, name: str, handler: ServiceHandler, lane: Lane) -> None:
        self.name = name
        self._handler = handler
        self._lane = lane
        self._key = context.key(name, "service")
        self._queryable = context.session.declare_queryable(self._key, self._on_query)

    def _on_query(self, query: zenoh.Query) -> None:
        # Zenoh's thread must not run user code that may block: hand the query to its owner's lane.
        self._lane(lambda: self._serve(query))

    def _serve(self, query: zenoh.Query) -> None:
        with query:  # dropping the query finalises it, so the caller stops waiting
            as_json = _wants_json(query)
            try:
                request = _read_request(query, as_json)
                result = self._handler(request)
                if not isinstance(result, dict):
                    raise TypeError(f"the handler returned {type(result).__name__}, not a dict")
                _reply(query, self._key, result, as_json)
            except Exception as exc:
                logger.debug("service %r failed: %s", self.name, exc)
                _reply_error(query, exc, as_json)

    def close(self) -> None:
        """Undeclare the queryable."""
        undeclare(self._queryable)


class ZenohPresence:
    """A component as Zenoh users see it: a liveliness token and the state / transition queryables."""

    def __init__(self, context: ZenohContext, name: str, on_transition: TransitionHandler, lane: Lane) -> None:
        self.name = name
        self._lane = lane
        self._on_transition = on_transition
        self._lock = threading.Lock()
        self._state = LifecycleState.UNCONFIGURED
        self._health = HealthStatus.HEALTHY
        self._message = ""
        self._closed = False
        ns = context.namespace
        self._state_key = state_key(ns, name)
        self._transition_key = transition_key(ns, name)
        session = context.session
        self._entities: list[Any] = [
            session.declare_queryable(self._state_key, self._on_state_query),
            session.declare_queryable(self._transition_key, self._on_transition_query),
            # Declared last: an observer that sees the token can query the state at once.
            session.liveliness().declare_token(liveliness_key(ns, name)),
        ]

    def update(self, state: LifecycleState, health: HealthStatus, message: str) -> None:
        """Set what the state queryable answers from now on."""
        with self._lock:
            self._state, self._health, self._message = state, health, message

    def status(self) -> ComponentStatusMsg:
        """The current state as the status message type."""
        with self._lock:
            return ComponentStatusMsg(component=self.name, lifecycle_state=self._state.value,
                                      health=self._health.name, message=self._message)

    def _on_state_query(self, query: zenoh.Query) -> None:
        # Cheap and non-blocking, so it is answered on Zenoh's thread.
        with query:
            try:
                status = self.status()
                if query.parameters.get("format") == "json":
                    doc = codec_for(ComponentStatus).encode(status)
                    query.reply(self._state_key, json.dumps(doc).encode(), encoding="application/json")
                else:
                    query.reply(self._state_key, encode_value(ComponentStatus, status),
                                encoding=zenoh.Encoding(MSGPACK).with_schema(ComponentStatus.type_name()))
            except Exception as exc:
                logger.warning("component %r: state query failed: %s", self.name, exc)

    def _on_transition_query(self, query: zenoh.Query) -> None:
        self._lane(lambda: self._serve_transition(query))

    def _serve_transition(self, query: zenoh.Query) -> None:
        with query:
            as_json = _wants_json(query)
            try:
                request = _read_request(query, as_json)
                transition = request.get("transition")
                if not isinstance(transition, str):
                    raise CodecError("a transition request is {'transition': '<name>'}")
                # The caller's timeout travels in the request map: a transition whose caller
                # gave up while it waited in the lane is not run.
                ok = serve_with_caller_deadline(lambda _: self._on_transition(transition), request,
                                                f"transition {transition!r} of {self.name!r}")
                _reply(query, self._transition_key, {"ok": bool(ok)}, as_json)
            except Exception as exc:
                _reply_error(query, exc, as_json)

    def close(self) -> None:
        """Withdraw the token and the queryables (observers see the component go); idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        for entity in reversed(self._entities):
            undeclare(entity)


def read_reply(reply: zenoh.Reply, what: str, timeout: float) -> dict[str, Any]:
    """The reply map of a service or transition query; raises RemoteError / RequestTimeoutError."""
    sample = reply.ok
    if sample is not None:
        try:
            doc = unpack(sample.payload.to_bytes())
        except CodecError as exc:
            raise RemoteError(f"{what} sent a reply that does not decode: {exc}") from exc
        if not isinstance(doc, dict):
            raise RemoteError(f"{what} replied a {type(doc).__name__}, not a map")
        return doc
    err = reply.err
    assert err is not None
    raw = err.payload.to_bytes()
    if str(err.encoding) == ERROR_ENCODING:
        try:
            message = str(unpack(raw)["error"])
        except (CodecError, KeyError, TypeError):
            message = repr(raw)
        raise RemoteError(f"{what} failed: {message}")
    text = raw.decode(errors="replace")
    if text == "Timeout":  # Zenoh's own error reply when the query's timeout expires
        raise RequestTimeoutError(f"request {what} got no reply within {timeout:g} s")
    raise RemoteError(f"{what} failed: {text}")
