"""The ROS 2 graph from rmw_zenoh's liveliness tokens: topics with their counts, and the lifecycle nodes.

Like rmw_zenoh's graph cache, a :class:`GraphCache` subscribes (with history) to every token of the domain
from the moment the session opens, so a graph read later holds every entity announced since, even through a
router that has only just learnt of them.
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import threading
import time
from typing import Any

import zenoh

from agents_core.transport.graph import Graph, TopicInfo

from .wire import TokenError, parse_token

__all__ = ["MAX_TOKENS", "GraphCache", "core_type_names", "graph_of"]

logger = logging.getLogger(__name__)


def core_type_names() -> dict[str, str]:
    """``pkg::msg::dds_::Type_`` -> the core's type name, for every registered conversion."""
    from agents_ros2.conversions import registered_conversions  # noqa: PLC0415

    from .typesupport import ros_type_name  # noqa: PLC0415
    from .wire import dds_type_name  # noqa: PLC0415

    names: dict[str, str] = {}
    for name, conversion in registered_conversions().items():
        try:
            names.setdefault(dds_type_name(ros_type_name(conversion.ros_type)), name)
        except Exception:  # a conversion without a ROS type name
            continue
    return names


#: Live tokens a graph cache holds at most (a busy ROS 2 graph has a few thousand); beyond it new ones are dropped.
MAX_TOKENS = 20_000
#: After tokens were dropped and room comes back: how long the cache waits for more withdrawals before it re-reads
#: the graph, the least time between two such re-reads, and how long one waits for the replies.
RESYNC_SETTLE_S = 0.2
RESYNC_INTERVAL_S = 1.0
RESYNC_TIMEOUT_S = 2.0


class GraphCache:
    """Every live token under ``@ros2_lv/<domain>/`` (bogus ones skipped and counted in ``bogus``).

    At most ``max_tokens`` tokens of other sessions are held, so that a hostile peer announcing tokens without end
    cannot grow it: past the bound new ones are dropped and counted in ``dropped`` (logged once). The tokens this
    driver declared (:meth:`claim`: the key alone proves nothing, as anyone may declare a token under our zid) are
    always held.
    Zenoh announces a live token once, so a dropped one would stay unseen: when room comes back after drops,
    the cache re-reads the domain's tokens once (a liveliness query, bounded in time and replies; counted in
    ``resyncs``), and again only after new drops.
    """

    def __init__(self, session: zenoh.Session, domain_id: int, max_tokens: int = MAX_TOKENS) -> None:
        self._lock = threading.Lock()
        self._tokens: set[str] = set()
        self._declared: set[str] = set()
        self.max_tokens = max_tokens
        self._session = session
        self._keys = f"@ros2_lv/{domain_id}/**"
        self.bogus = 0
        self.dropped = 0
        self.resyncs = 0
        self._missed = False  # tokens were dropped since the last re-read
        self._withdrawn: set[str] | None = None  # during a re-read: the keys withdrawn meanwhile
        self._resync: threading.Thread | None = None
        self._last_resync = 0.0
        self._closed = threading.Event()
        self.opened = time.monotonic()
        self._sub: Any = session.liveliness().declare_subscriber(self._keys, self._on_token, history=True)

    def claim(self, token: str) -> None:
        """``token`` is this driver's (call it before declaring the token): always held."""
        with self._lock:
            self._declared.add(token)

    def release(self, token: str) -> None:
        """``token`` was withdrawn by this driver."""
        with self._lock:
            self._declared.discard(token)

    def _on_token(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        with self._lock:
            if sample.kind != zenoh.SampleKind.DELETE:
                self._add(key)
                return
            self._tokens.discard(key)
            if self._withdrawn is not None and len(self._withdrawn) <= self.max_tokens:
                self._withdrawn.add(key)  # past the bound the re-read is discarded (and done again)
            self._reread_if_lost()

    def _reread_if_lost(self) -> None:
        """Start a re-read (the lock held) if tokens were dropped, room came back and none is under way."""
        if self._missed and self._resync is None and len(self._tokens) < self.max_tokens \
                and not self._closed.is_set():
            self._resync = threading.Thread(target=self._reread, name="rmw-graph-resync", daemon=True)
            self._resync.start()

    def _add(self, key: str) -> None:
        """Hold ``key`` (the lock held), unless it is bogus or the cache is full."""
        if key in self._tokens:
            return
        try:
            parse_token(key)
        except TokenError as exc:
            self.bogus += 1
            logger.debug("skipped a liveliness token: %s", exc)
            return
        if len(self._tokens) >= self.max_tokens and key not in self._declared:
            self.dropped += 1
            self._missed = True
            if self.dropped == 1:
                logger.warning("rmw_zenoh: the graph holds %d liveliness tokens, its bound; new ones are "
                               "dropped (and counted) until some are withdrawn", self.max_tokens)
            return
        self._tokens.add(key)

    def _reread(self) -> None:
        """Re-read the domain's live tokens once (on its own thread, not Zenoh's): those dropped come back."""
        try:
            wait = max(RESYNC_SETTLE_S, self._last_resync + RESYNC_INTERVAL_S - time.monotonic())
            if self._closed.wait(wait):
                return
            with self._lock:
                self._missed, self._withdrawn = False, set()
            found: list[str] = []
            with contextlib.suppress(zenoh.ZError):
                replies = self._session.liveliness().get(self._keys, timeout=RESYNC_TIMEOUT_S)
                for reply in itertools.islice(replies, 2 * self.max_tokens + len(self._declared) + 1024):
                    if reply.ok is not None:
                        found.append(str(reply.ok.key_expr))
            with self._lock:
                withdrawn, self._withdrawn = self._withdrawn, None
                if withdrawn is None or len(withdrawn) > self.max_tokens:
                    self._missed = True  # too many withdrawn meanwhile to tell a stale reply: done again later
                    return
                for key in found:
                    if key not in withdrawn:  # a reply may predate the token's withdrawal
                        self._add(key)
                self.resyncs += 1
        finally:
            with self._lock:
                self._resync, self._last_resync = None, time.monotonic()
                self._reread_if_lost()  # dropped again meanwhile, with room now: once more (not before the interval)

    def tokens(self, settle: float) -> set[str]:
        """The live tokens, once the cache is at least ``settle`` seconds old."""
        wait = self.opened + settle - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        with self._lock:
            return set(self._tokens)

    def close(self) -> None:
        """Stop watching."""
        self._closed.set()
        with contextlib.suppress(zenoh.ZError):
            self._sub.undeclare()
        resync = self._resync
        if resync is not None:
            resync.join(RESYNC_TIMEOUT_S + 1.0)


def graph_of(tokens: set[str]) -> Graph:
    """A :class:`Graph` of tokens: MP / MS counted per topic and type; a node serving its own ``change_state``
    (``/robot1/arm/change_state`` of node ``arm`` in namespace ``/robot1``, as ROS 2 lifecycle nodes do) is a
    component, named by its fully qualified name without the leading '/' (``robot1/arm``)."""
    counts: dict[tuple[str, str], list[int]] = {}
    components: set[str] = set()
    names = core_type_names()
    for key in tokens:
        token = parse_token(key)
        if token.kind in ("MP", "MS"):
            fallback = token.ros_type.replace("::dds_::", "/").replace("::", "/").removesuffix("_")
            entry = counts.setdefault((token.name.lstrip("/"), names.get(token.ros_type, fallback)), [0, 0])
            entry[0 if token.kind == "MP" else 1] += 1
        elif token.kind == "SS" and token.name == f"{token.namespace.rstrip('/')}/{token.node}/change_state":
            components.add(token.name.lstrip("/").removesuffix("/change_state"))
    topics = [TopicInfo(name=n, msg_type=t, publishers=p, subscribers=s) for (n, t), (p, s) in counts.items()]
    return Graph(topics=topics, components=sorted(components))
