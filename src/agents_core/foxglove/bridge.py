"""``FoxgloveBridge``: a recipe's topics served live over the Foxglove WebSocket protocol.

The bridge subscribes to each topic through the :class:`~agents_core.transport.contract.Transport`
contract (memory, Zenoh, ROS 2 alike) and logs what arrives to a ``foxglove-sdk`` WebSocket server
(:mod:`.feeds` says what each type becomes). The recipe never waits for it: each subscription's
queue holds ``settings.queue_depth`` values (1 by default: drop-to-latest), a full one drops the
oldest and counts it (:meth:`FoxgloveBridge.statistics`), and the conversion runs on that
subscription's delivery thread. It advertises no client capability: a Foxglove client can look,
not publish into the recipe.

Clients do not reach the ``foxglove-sdk`` server itself: it listens on a hidden loopback port
(TLS with a key of its own when ``cryptography`` is installed), and :class:`~.guard.FoxgloveGuard`
on the port clients are given bounds what the SDK cannot: each client's buffer in bytes (latest
frame wins for images), the number of clients, the handshake's time, and web page origins.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

import attrs
import foxglove

from ..topics import Topic
from ..transport.delivery import SubscriptionStatistics
from .feeds import TopicFeed
from .guard import FoxgloveGuard, GuardStatistics, hidden_hop_tls
from .settings import FoxgloveSettings

if TYPE_CHECKING:
    from ..transport.contract import Subscription, Transport

__all__ = ["FoxgloveBridge"]

logger = logging.getLogger(__name__)


class FoxgloveBridge:
    """Serve ``topics`` of ``transport`` to Foxglove clients; :meth:`start` it, :meth:`stop` it.

    :param transport: the transport the recipe runs on (the caller keeps and closes it).
    :param topics: the topics to serve; more can be added later with :meth:`add_topics`.
    :param settings: where to listen (loopback by default) and the queue bounds.
    """

    def __init__(self, transport: Transport, topics: Iterable[Topic] = (),
                 settings: FoxgloveSettings | None = None) -> None:
        self.settings = settings or FoxgloveSettings()
        self._transport = transport
        self._pending = list(topics)
        self._context = foxglove.Context()
        self._feeds: dict[str, tuple[TopicFeed, Subscription]] = {}
        self._lock = threading.Lock()
        self._server: Any = None
        self._guard: FoxgloveGuard | None = None

    def start(self) -> FoxgloveBridge:
        """Listen, advertise the topics and subscribe to them; returns self."""
        tls = hidden_hop_tls()
        if tls is None:
            logger.warning("Foxglove bridge: without the 'cryptography' package the hidden hop to the SDK's "
                           "server is plain ws:// on loopback; a web page that finds its port could reach it")
        self._server = foxglove.start_server(
            name="agents_core", host="127.0.0.1", port=0, context=self._context, capabilities=[],
            message_backlog_size=self.settings.client_backlog,
            tls_cert=tls[0] if tls else None, tls_key=tls[1] if tls else None)
        try:
            self._guard = FoxgloveGuard(self.settings.host, self.settings.port, int(self._server.port), self.settings,
                                        tls[2] if tls else None).start()
            self.add_topics(self._pending)
        except BaseException:
            self.stop()
            raise
        logger.info("Foxglove bridge on %s serving %d topic(s)", self.url, len(self._feeds))
        return self

    @property
    def port(self) -> int:
        """The TCP port clients connect to (the one picked when ``settings.port`` is 0)."""
        if self._server is None or self._guard is None:
            raise RuntimeError("the Foxglove bridge is not started")
        return self._guard.port

    def guard_statistics(self) -> GuardStatistics:
        """What the guard refused and dropped: clients and origins refused, handshakes timed out, ..."""
        if self._guard is None:
            raise RuntimeError("the Foxglove bridge is not started")
        return self._guard.stats

    @property
    def url(self) -> str:
        """``ws://host:port``: what to give Foxglove's "Open connection" dialog."""
        host = self.settings.host
        return f"ws://{'[' + host + ']' if ':' in host else host}:{self.port}"

    def topics(self) -> list[str]:
        """Our topics served, sorted."""
        with self._lock:
            return sorted(self._feeds)

    def add_topics(self, topics: Iterable[Topic]) -> list[str]:
        """Serve these topics too (one already served is skipped); returns the names added."""
        added = []
        for topic in topics:
            with self._lock:
                if self._server is None or topic.name in self._feeds:
                    continue
                feed = TopicFeed(topic, self._context, self.settings.max_text_chars)
                # Our own bounded queue: drop-to-latest, whatever depth the recipe's topic has.
                qos = attrs.evolve(topic.qos_profile, depth=self.settings.queue_depth)
                try:
                    sub = self._transport.create_subscription(Topic(topic.name, topic.msg_type, qos_profile=qos),
                                                              self._callback(feed))
                except BaseException:
                    feed.close()
                    raise
                self._feeds[topic.name] = (feed, sub)
                added.append(topic.name)
        return added

    def statistics(self) -> dict[str, SubscriptionStatistics]:
        """Per served topic: delivered, dropped (queue full: drop-to-latest), callback_errors, ..."""
        with self._lock:
            return {name: sub.statistics() for name, (_, sub) in self._feeds.items()}

    def stop(self) -> None:
        """Unsubscribe, withdraw the channels and stop the server; idempotent."""
        with self._lock:
            feeds, self._feeds = list(self._feeds.values()), {}
            server, self._server = self._server, None
            guard, self._guard = self._guard, None
        if guard is not None:
            guard.stop()
        for feed, sub in feeds:
            sub.close()
            feed.close()
        if server is not None:
            server.stop()

    def _callback(self, feed: TopicFeed) -> Any:
        def show(value: Any) -> None:
            # Raising is counted by the subscription (callback_errors) and logged once; the bridge goes on.
            feed.show(value)

        return show

    def __enter__(self) -> FoxgloveBridge:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
