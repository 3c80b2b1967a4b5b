"""The ROS 2 graph from rmw_zenoh's liveliness tokens: topics with their counts, and the lifecycle nodes.

Like rmw_zenoh's graph cache, a :class:`GraphCache` subscribes (with history) to every token of the domain
from the moment the session opens, so a graph read later holds every entity announced since, even through a
router that has only just learnt of them.
"""

from __future__ import annotations

import contextlib
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


class GraphCache:
    """Every live token under ``@ros2_lv/<domain>/`` (bogus ones skipped and counted in ``bogus``).

    At most ``max_tokens`` of other sessions' tokens are held, so that a hostile peer announcing tokens without
    end cannot grow it: past the bound new ones are dropped and counted in ``dropped`` (logged once), and room
    comes back as tokens are withdrawn. The tokens of ``own_zid`` (this session's entities) are always held.
    """

    def __init__(self, session: zenoh.Session, domain_id: int, max_tokens: int = MAX_TOKENS,
                 own_zid: str | None = None) -> None:
        self._lock = threading.Lock()
        self._tokens: set[str] = set()
        self.max_tokens = max_tokens
        self._own = f"@ros2_lv/{domain_id}/{own_zid or session.zid()}/"
        self.bogus = 0
        self.dropped = 0
        self.opened = time.monotonic()
        self._sub: Any = session.liveliness().declare_subscriber(f"@ros2_lv/{domain_id}/**", self._on_token,
                                                                 history=True)

    def _on_token(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        with self._lock:
            if sample.kind == zenoh.SampleKind.DELETE:
                self._tokens.discard(key)
                return
            if key in self._tokens:
                return
            try:
                parse_token(key)
            except TokenError as exc:
                self.bogus += 1
                logger.debug("skipped a liveliness token: %s", exc)
                return
            if len(self._tokens) >= self.max_tokens and not key.startswith(self._own):
                self.dropped += 1
                if self.dropped == 1:
                    logger.warning("rmw_zenoh: the graph holds %d liveliness tokens, its bound; new ones are "
                                   "dropped (and counted) until some are withdrawn", self.max_tokens)
                return
            self._tokens.add(key)

    def tokens(self, settle: float) -> set[str]:
        """The live tokens, once the cache is at least ``settle`` seconds old."""
        wait = self.opened + settle - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        with self._lock:
            return set(self._tokens)

    def close(self) -> None:
        """Stop watching."""
        with contextlib.suppress(zenoh.ZError):
            self._sub.undeclare()


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
