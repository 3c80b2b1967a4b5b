"""``OutputHub``: one subscription per shown topic, fanned out to every WebSocket client.

Each value is encoded to its frame once, on the subscription's delivery thread, then handed to
the server's event loop, which puts it in each interested client's queue. A client's queue is
bounded (:attr:`OutputHub.client_queue`); a client that lets it fill up is too slow to follow
and is dropped (its WebSocket closed with code 1013), never buffered without bound. The hub also
watches each component's status topic and keeps the latest status for ``/api/interfaces``.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import threading
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any

from ..transport.core import status_topic
from .frames import FrameRefused, error_frame, frame_for

if TYPE_CHECKING:
    from ..topics import Topic
    from ..transport.contract import Subscription, Transport

__all__ = ["OutputClient", "OutputHub"]

logger = logging.getLogger(__name__)


class OutputClient:
    """One WebSocket client's bounded queue of encoded frames (None: the client was dropped)."""

    def __init__(self, topics: frozenset[str] | None, depth: int) -> None:
        #: The topics it asked for (None: all); status frames always come.
        self.topics = topics
        self.queue: asyncio.Queue[str | None] = asyncio.Queue(maxsize=depth + 1)  # + 1 for the drop marker
        self.depth = depth
        self.dropped = False
        #: Called on the event loop when the client is dropped (its handler stops a send that is stuck).
        self.on_drop: Callable[[], object] | None = None

    def wants(self, topic: str, kind: str) -> bool:
        return kind == "status" or self.topics is None or topic in self.topics


class OutputHub:
    """Subscribes to ``outputs`` and to the status topics of ``components`` on ``transport``.

    :param image_format: ``"jpeg"`` or ``"png"`` for raw images.
    :param client_queue: frames a client may have waiting before it is dropped.
    """

    def __init__(self, transport: Transport, outputs: Iterable[Topic], components: Iterable[str], *,
                 image_format: str = "jpeg", client_queue: int = 256) -> None:
        self._transport = transport
        self.outputs = {t.name: t for t in outputs}
        self.components = sorted(set(components))
        self.image_format = image_format
        self.client_queue = client_queue
        self._clients: set[OutputClient] = set()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._subscriptions: list[Subscription] = []
        self._lock = threading.Lock()
        self._status: dict[str, dict[str, Any]] = {}
        self.frames_sent = 0
        self.encode_errors = 0
        self.dropped_clients = 0
        #: WebSocket clients turned away because ``max_clients`` were connected.
        self.refused_clients = 0

    # -- life ---------------------------------------------------------------------------------

    def start(self, loop: asyncio.AbstractEventLoop) -> None:
        """Subscribe; frames are handed to ``loop`` (the server's)."""
        self._loop = loop
        for topic in self.outputs.values():
            self._subscriptions.append(self._transport.create_subscription(topic, self._receiver(topic)))
        for name in self.components:
            topic = status_topic(name)
            self._subscriptions.append(self._transport.create_subscription(topic, self._receiver(topic)))

    def stop(self) -> None:
        """Close every subscription (no frame is handed over after this returns)."""
        subscriptions, self._subscriptions = self._subscriptions, []
        for sub in subscriptions:
            try:
                sub.close()
            except Exception as exc:
                logger.debug("closing %s: %s", sub.topic.name, exc)
        self._loop = None

    # -- frames -------------------------------------------------------------------------------

    def _receiver(self, topic: Topic) -> Any:
        name, type_name = topic.name, topic.msg_type.type_name()

        def receive(value: Any) -> None:
            try:
                frame = frame_for(name, type_name, value, self.image_format)
                text = json.dumps(frame, separators=(",", ":"), allow_nan=False)
            except Exception as exc:
                # Clients get an error frame in its place: a value is never lost without a word.
                self.encode_errors += 1
                if isinstance(exc, FrameRefused):
                    logger.warning("a value of topic %r is not shown: %s", name, exc)
                else:  # a value the encoder should have handled: worth the traceback in the log
                    logger.exception("the UI could not encode a value of topic %r", name)
                frame = error_frame(name, type_name, value, f"this value could not be shown: {exc}")
                text = json.dumps(frame, separators=(",", ":"))
            if frame["kind"] == "status":
                with self._lock:
                    self._status[frame["component"]] = frame
            loop = self._loop
            if loop is not None:
                with contextlib.suppress(RuntimeError):  # the loop closed while the server stops
                    loop.call_soon_threadsafe(self._fan_out, name, frame["kind"], text)

        return receive

    def _fan_out(self, topic: str, kind: str, text: str) -> None:
        """On the event loop: queue ``text`` for every interested client; drop the ones that are full."""
        for client in list(self._clients):
            if client.dropped or not client.wants(topic, kind):
                continue
            if client.queue.qsize() >= client.depth:
                self._drop(client)
                continue
            client.queue.put_nowait(text)
            self.frames_sent += 1

    def _drop(self, client: OutputClient) -> None:
        client.dropped = True
        self.dropped_clients += 1
        while not client.queue.empty():
            client.queue.get_nowait()
        client.queue.put_nowait(None)
        if client.on_drop is not None:
            client.on_drop()
        logger.warning("a UI client fell %d frames behind and was dropped", client.depth)

    # -- clients ------------------------------------------------------------------------------

    def connect(self, topics: Iterable[str] | None = None) -> OutputClient:
        """A new client (on the event loop), following ``topics`` (None: every shown output)."""
        client = OutputClient(frozenset(topics) if topics is not None else None, self.client_queue)
        self._clients.add(client)
        with self._lock:
            known = list(self._status.values())
        for frame in known[: client.depth]:  # the current status of each component, first
            client.queue.put_nowait(json.dumps(frame, separators=(",", ":")))
        return client

    def disconnect(self, client: OutputClient) -> None:
        self._clients.discard(client)

    @property
    def client_count(self) -> int:
        return len(self._clients)

    def latest_status(self, component: str) -> dict[str, Any] | None:
        """The last status frame seen for ``component``, or None."""
        with self._lock:
            return self._status.get(component)
