"""What the goal server (:mod:`agents_zenoh.goals`) and client (:mod:`agents_zenoh.goal_client`) share.

The constants and request checks of the goal protocol, and the helpers that answer a query. The
protocol itself is described in :mod:`agents_zenoh.goals` and ``docs/zenoh-wire-format.md``.
"""

from __future__ import annotations

import logging
import math
from typing import Any

import zenoh

from .codecs import MSGPACK, CodecError, pack, unpack

__all__ = ["KIND_FEEDBACK", "KIND_GOAL", "KIND_RESULT", "KIND_STATUS", "MAX_STREAM_S", "STREAM_S", "answer",
           "answer_error", "cancel_token", "finalize", "request", "result_wait", "stream_seconds"]

logger = logging.getLogger(__name__)

#: How long one result query waits on the server before it answers ``pending`` (client asks, server caps).
RESULT_WAIT_S = 1.0
MAX_RESULT_WAIT_S = 5.0
#: Length bounds of a cancel token (ours: 32 hex digits, 128 random bits).
MIN_CANCEL_TOKEN, MAX_CANCEL_TOKEN = 16, 128
#: How long a goal stream stays open (the stream query's timeout, asked by the client, capped by the
#: server): a goal that runs longer is followed by samples and result queries instead.
STREAM_S = 3600.0
MAX_STREAM_S = 3600.0
#: The ``kind`` of each reply on a goal stream: the decision, then feedback and status, then the result.
KIND_GOAL, KIND_FEEDBACK, KIND_STATUS, KIND_RESULT = "goal", "feedback", "status", "result"


def request(query: zenoh.Query) -> dict[str, Any]:
    """The query's msgpack map (decoded under the default limits); CodecError otherwise."""
    payload = query.payload
    if payload is None or len(payload) == 0:
        raise CodecError("the request is empty")
    doc = unpack(payload.to_bytes())
    if not isinstance(doc, dict):
        raise CodecError(f"a request must be a map, got {type(doc).__name__}")
    return doc


def cancel_token(doc: dict[str, Any], what: str) -> str | None:
    """The request's ``cancel_token`` (None when absent); CodecError for one that is not a fitting str."""
    token = doc.get("cancel_token")
    if token is None:
        return None
    if not isinstance(token, str) or not MIN_CANCEL_TOKEN <= len(token) <= MAX_CANCEL_TOKEN \
            or not token.isascii():
        raise CodecError(f"a {what}'s cancel_token must be an ASCII str of {MIN_CANCEL_TOKEN} to "
                         f"{MAX_CANCEL_TOKEN} characters")
    return token


def _seconds(value: Any, cap: float, what: str) -> float:
    # A NaN deadline compares false with every time, so whatever waits on it would never end.
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise CodecError(f"{what} must be a number of seconds")
    if math.isnan(value):
        raise CodecError(f"{what} must be a number of seconds, not NaN")
    return min(max(float(value), 0.0), cap)


def result_wait(wait: Any) -> float:
    """The seconds a result query may be held: ``wait_s`` clamped to 0..MAX_RESULT_WAIT_S (NaN refused)."""
    if isinstance(wait, bool) or not isinstance(wait, int | float):
        raise CodecError("a result request is {'goal_id': str, 'wait_s': number}")
    return _seconds(wait, MAX_RESULT_WAIT_S, "a result request's wait_s")


def stream_seconds(value: Any) -> float:
    """How long a goal stream's client keeps listening: ``stream_s`` clamped to 0..MAX_STREAM_S (NaN refused)."""
    return _seconds(value, MAX_STREAM_S, "a goal stream's stream_s")


def answer(query: zenoh.Query, doc: dict[str, Any], *, express: bool = False) -> bool:
    """Reply ``doc`` to ``query``; False when Zenoh refused (the query is gone).

    ``express`` sends it at once rather than batched with what follows: for a reply the caller
    waits for (costlier per message, so not for a stream's feedback).
    """
    try:
        query.reply(query.key_expr, pack(doc), encoding=MSGPACK, express=express)
    except zenoh.ZError as exc:
        logger.debug("could not answer %s: %s", query.key_expr, exc)
        return False
    return True


def answer_error(query: zenoh.Query, reason: str) -> None:
    """An error reply ``{"error": reason, "type": "CodecError"}``."""
    try:
        query.reply_err(pack({"error": reason, "type": "CodecError"}), encoding=f"{MSGPACK};error")
    except zenoh.ZError as exc:
        logger.debug("could not send an error reply: %s", exc)


def finalize(query: zenoh.Query) -> None:
    """End a held query: its caller stops waiting for more replies."""
    query.drop()  # type: ignore[no-untyped-call]  # zenoh's stub leaves it unannotated
