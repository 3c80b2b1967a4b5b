"""Who may use the UI: the token check, login sessions and the throttle on wrong tokens.

A successful ``POST /api/login`` does not put the token in the cookie: it creates a session, an
opaque random id (:func:`secrets.token_urlsafe`) that the server maps to an expiry time. The
cookie carries only that id, so a cookie that leaks (a backup of a browser profile, a shared
machine) is worth nothing after ``session_seconds`` and never reveals the token itself.

Wrong tokens (at login or in an ``Authorization`` header) are counted per client address: after
:data:`MAX_FAILURES` within :data:`FAILURE_WINDOW` seconds that address is answered 429 until the
window passes, so a token cannot be guessed at network speed. Both tables are bounded.
"""

from __future__ import annotations

import hmac
import secrets
import threading
import time
from collections import OrderedDict, deque
from collections.abc import Callable

__all__ = ["FAILURE_WINDOW", "MAX_FAILURES", "MAX_SESSIONS", "Gatekeeper"]

#: Wrong tokens an address may present within :data:`FAILURE_WINDOW` seconds before it is answered 429.
MAX_FAILURES = 5
FAILURE_WINDOW = 10.0
#: Live sessions kept at once; the oldest is forgotten (logged out) past it.
MAX_SESSIONS = 256
#: Addresses whose failures are remembered at once (an address flood cannot grow the table).
_MAX_ADDRESSES = 4096


class Gatekeeper:
    """The token, the live sessions and the recent failures of each client address (thread-safe).

    :param token: the secret; None means no token is needed.
    :param session_seconds: how long a session lasts after login.
    :param clock: seconds, monotonic (tests pass their own).
    """

    def __init__(self, token: str | None, session_seconds: float,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self._token = token.encode() if token is not None else None
        self.session_seconds = session_seconds
        self._now = clock
        self._sessions: OrderedDict[str, float] = OrderedDict()
        self._failures: OrderedDict[str, deque[float]] = OrderedDict()
        self._lock = threading.Lock()

    @property
    def token_needed(self) -> bool:
        """Whether clients must present the token (or a session)."""
        return self._token is not None

    def throttled(self, address: str) -> float:
        """Seconds ``address`` must wait before presenting a token again (0: it may now)."""
        now = self._now()
        with self._lock:
            if address not in self._failures:  # asking creates no entry: only failures take room
                return 0.0
            recent = self._recent(address, now)
            if len(recent) < MAX_FAILURES:
                return 0.0
            return max(0.0, recent[0] + FAILURE_WINDOW - now)

    def check_token(self, address: str, presented: str) -> bool:
        """Whether ``presented`` is the token (constant time); a wrong one counts against ``address``."""
        if self._token is None:
            return True
        # As bytes: a str with a lone surrogate (valid JSON, "\ud800") encodes, it does not raise.
        if hmac.compare_digest(presented.encode("utf-8", "surrogatepass"), self._token):
            return True
        now = self._now()
        with self._lock:
            self._recent(address, now).append(now)
            self._failures.move_to_end(address)
            while len(self._failures) > _MAX_ADDRESSES:
                self._failures.popitem(last=False)
        return False

    def _recent(self, address: str, now: float) -> deque[float]:
        recent = self._failures.setdefault(address, deque(maxlen=MAX_FAILURES))
        while recent and recent[0] + FAILURE_WINDOW <= now:
            recent.popleft()
        return recent

    def open_session(self) -> str:
        """A new session id (the cookie's value), valid for ``session_seconds``."""
        session = secrets.token_urlsafe(32)
        now = self._now()
        with self._lock:
            self._sessions[session] = now + self.session_seconds
            while len(self._sessions) > MAX_SESSIONS:
                self._sessions.popitem(last=False)
        return session

    def session_valid(self, session: str) -> bool:
        """Whether ``session`` is a live session id (an expired one is forgotten)."""
        now = self._now()
        with self._lock:
            expiry = self._sessions.get(session)
            if expiry is None:
                return False
            if expiry <= now:
                del self._sessions[session]
                return False
            return True

    def close_session(self, session: str) -> None:
        """Forget ``session`` (logout)."""
        with self._lock:
            self._sessions.pop(session, None)
