"""``OutputHub``: one subscription per shown topic, fanned out to every WebSocket client.

Each value is encoded to its frame once, on the subscription's delivery thread, then handed to
the server's event loop, which puts it in each interested client's queue. A client's queue is
bounded (:attr:`OutputHub.client_queue`); a client that lets it fill up is too slow to follow
and is dropped (its WebSocket closed with code 1013), never buffered without bound. The hub also
watches each component's status topic and keeps the latest status for ``/api/interfaces``.

A client of binary frames (``?frames=binary``, what the page opens) gets images as binary frames
(:mod:`.binary_frames`), and its image and detections frames are *latest-wins* per topic: while one
is waiting to be sent, a newer one replaces it (counted in :attr:`OutputHub.dropped_frames`) rather
than queueing behind it, so a camera faster than the client's link or screen is shown at the rate
the client takes, never buffered, and such a client is not dropped for being slow at images.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import threading
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any

from ..messages import CompressedImageMsg, ImageMsg
from ..transport.core import status_topic
from .binary_frames import pack_image
from .frames import FrameRefused, error_frame, frame_for, image_bytes

if TYPE_CHECKING:
    from ..topics import Topic
    from ..transport.contract import Subscription, Transport

__all__ = ["LATEST_WINS", "OutputClient", "OutputHub"]

logger = logging.getLogger(__name__)

#: Frame kinds that binary clients get latest-wins per topic (only the newest is worth drawing).
LATEST_WINS = frozenset({"image", "detections"})


class _Latest:
    """A queue entry that stands for the newest frame of ``topic`` waiting in ``OutputClient.latest``."""

    __slots__ = ("topic",)

    def __init__(self, topic: str) -> None:
        self.topic = topic


class _ImageFrames:
    """One image value's frames, each encoded at most once: JSON text for JSON clients, binary for the others.

    Encoded on the delivery thread for the kinds of client connected then, and on the event loop for a
    kind that connected in between (rare).
    """

    def __init__(self, hub: OutputHub, topic: str, type_name: str, value: Any) -> None:
        self._hub, self._topic, self._type, self._value = hub, topic, type_name, value
        self._text: str | None = None
        self._binary: bytes | str | None = None
        self._binary_full: bytes | str | None = None

    def text(self) -> str:
        if self._text is None:
            self._text = self._hub.encode(self._topic, self._type, self._value)[1]
        return self._text

    def binary(self, full: bool = False) -> bytes | str:
        """The binary frame: the preview (``hub.image_preview``), or the image at full resolution."""
        if full and self._hub.image_preview is not None:
            if self._binary_full is None:
                self._binary_full = self._encode_binary(None)
            return self._binary_full
        if self._binary is None:
            self._binary = self._encode_binary(self._hub.image_preview)
        return self._binary

    def _encode_binary(self, max_side: int | None) -> bytes | str:
        hub, value = self._hub, self._value
        try:
            mime, data, width, height, _ = image_bytes(value, hub.image_format, max_side)
        except Exception:
            return self.text()  # the JSON path says why, in an error frame (and counts it)
        header = getattr(value, "header", None)
        packed = pack_image(hub.topic_ids.get(self._topic, 0), mime, data, width, height,
                            getattr(header, "stamp_ns", None))
        return packed if packed is not None else self.text()  # e.g. a CompressedImage in another format


#: How much older than the status shown a status may be stamped and still be taken for a late backlog value.
_STALE_STATUS_NS = 5_000_000_000


class OutputClient:
    """One WebSocket client's bounded queue of encoded frames (None: the client was dropped)."""

    def __init__(self, topics: frozenset[str] | None, depth: int, binary: bool = False, full: bool = False) -> None:
        #: The topics it asked for (None: all); status frames always come.
        self.topics = topics
        #: Unbounded as a queue, bounded by the hub: at most ``depth`` frames plus one entry per topic in
        #: ``latest`` plus the drop marker.
        self.queue: asyncio.Queue[str | bytes | _Latest | None] = asyncio.Queue()
        self.depth = depth
        #: Images as binary frames, image / detections frames latest-wins (see the module docstring).
        self.binary = binary
        #: Images at full resolution rather than the hub's preview size (binary clients that asked).
        self.full = full
        #: topic -> its newest latest-wins frame not sent yet.
        self.latest: dict[str, str | bytes] = {}
        #: Latest-wins frames replaced by a newer one before they were sent.
        self.dropped_frames = 0
        self.dropped = False
        #: Called on the event loop when the client is dropped (its handler stops a send that is stuck).
        self.on_drop: Callable[[], object] | None = None
        #: component -> the arrival number of the newest status it was sent (older ones are not sent).
        self.status_seen: dict[str, int] = {}

    def wants(self, topic: str, kind: str) -> bool:
        return kind == "status" or self.topics is None or topic in self.topics

    @property
    def backlog(self) -> int:
        """Frames waiting that count against ``depth`` (latest-wins ones do not: one per topic at most)."""
        return self.queue.qsize() - len(self.latest)

    async def next_frame(self) -> str | bytes | None:
        """The next frame to send (None: the client was dropped)."""
        item = await self.queue.get()
        if isinstance(item, _Latest):
            return self.latest.pop(item.topic)
        return item


class OutputHub:
    """Subscribes to ``outputs`` and to the status topics of ``components`` on ``transport``.

    :param image_format: ``"jpeg"`` or ``"png"`` for raw images.
    :param client_queue: frames a client may have waiting before it is dropped.
    :param image_preview: binary clients get raw images downscaled so their longest side is at most
        this (a whole step: 640x480 -> 320x240 at 320), unless they asked for full resolution; None:
        always full.
    """

    def __init__(self, transport: Transport, outputs: Iterable[Topic], components: Iterable[str], *,
                 image_format: str = "jpeg", client_queue: int = 256, image_preview: int | None = None) -> None:
        self._transport = transport
        self.outputs = {t.name: t for t in outputs}
        self.components = sorted(set(components))
        self.image_format = image_format
        self.image_preview = image_preview
        self.client_queue = client_queue
        self._clients: set[OutputClient] = set()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._subscriptions: list[Subscription] = []
        self._lock = threading.Lock()
        self._status: dict[str, dict[str, Any]] = {}
        #: component -> (arrival number, text) of its newest status frame: what a status fan-out sends.
        self._status_text: dict[str, tuple[int, str]] = {}
        self._status_count = 0
        #: output topic -> the ``topic_id`` of its binary frames (its place in ``outputs``).
        self.topic_ids = {name: i for i, name in enumerate(self.outputs)}
        self._binary_clients = 0
        self._full_clients = 0
        self._json_clients = 0
        self.frames_sent = 0
        #: Latest-wins frames replaced before they were sent, over every client.
        self.dropped_frames = 0
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

    def encode(self, name: str, type_name: str, value: Any) -> tuple[dict[str, Any], str]:
        """The JSON frame of ``value`` and its text; an ``error`` frame (counted) when it cannot be shown."""
        try:
            frame = frame_for(name, type_name, value, self.image_format)
            return frame, json.dumps(frame, separators=(",", ":"), allow_nan=False)
        except Exception as exc:
            # Clients get an error frame in its place: a value is never lost without a word.
            self.encode_errors += 1
            if isinstance(exc, FrameRefused):
                logger.warning("a value of topic %r is not shown: %s", name, exc)
            else:  # a value the encoder should have handled: worth the traceback in the log
                logger.exception("the UI could not encode a value of topic %r", name)
            frame = error_frame(name, type_name, value, f"this value could not be shown: {exc}")
            return frame, json.dumps(frame, separators=(",", ":"))

    def _receiver(self, topic: Topic) -> Any:
        name, type_name = topic.name, topic.msg_type.type_name()

        def receive(value: Any) -> None:
            payload: str | _ImageFrames
            if isinstance(value, ImageMsg | CompressedImageMsg):
                kind, payload = "image", _ImageFrames(self, name, type_name, value)
                # Encoded here, off the event loop, in the forms the clients connected now take.
                if self._binary_clients > self._full_clients:
                    payload.binary()
                if self._full_clients:
                    payload.binary(full=True)
                if self._json_clients:
                    payload.text()
            else:
                frame, payload = self.encode(name, type_name, value)
                kind = frame["kind"]
                if kind == "status":
                    component = frame["component"]
                    with self._lock:
                        known = self._status.get(component)
                        stamp, shown = int(frame.get("stamp_ns") or 0), int((known or {}).get("stamp_ns") or 0)
                        # Stamped shortly before the status shown: a late backlog value, not news. Only shortly:
                        # a sender whose clock stepped back must not be silenced until it catches up (statuses
                        # come again every second or so, so an older stale one is replaced at once).
                        if stamp and shown and 0 < shown - stamp < _STALE_STATUS_NS:
                            return
                        self._status_count += 1
                        self._status[component] = frame
                        self._status_text[component] = (self._status_count, payload)
                    loop = self._loop
                    if loop is not None:
                        with contextlib.suppress(RuntimeError):
                            loop.call_soon_threadsafe(self._fan_out_status, component)
                    return
            loop = self._loop
            if loop is not None:
                with contextlib.suppress(RuntimeError):  # the loop closed while the server stops
                    loop.call_soon_threadsafe(self._fan_out, name, kind, payload)

        return receive

    def _fan_out(self, topic: str, kind: str, payload: str | _ImageFrames) -> None:
        """On the event loop: queue the frame for every interested client; drop the ones that are full."""
        for client in list(self._clients):
            if client.dropped or not client.wants(topic, kind):
                continue
            if isinstance(payload, str):
                data: str | bytes = payload
            else:
                data = payload.binary(client.full) if client.binary else payload.text()
            if client.binary and kind in LATEST_WINS:
                if topic in client.latest:  # the older one was not sent yet: the newer replaces it
                    client.dropped_frames += 1
                    self.dropped_frames += 1
                else:
                    client.queue.put_nowait(_Latest(topic))
                    self.frames_sent += 1
                client.latest[topic] = data
                continue
            if client.backlog >= client.depth:
                self._drop(client)
                continue
            client.queue.put_nowait(data)
            self.frames_sent += 1

    def _fan_out_status(self, component: str) -> None:
        """On the event loop: send each client ``component``'s newest status, unless it has it already.

        Status is latest-wins: a fan-out scheduled for an older status (a transient-local backlog still
        being delivered, or a burst of transitions) sends the newest one instead, and a client never gets a
        status older than one it was given, so a page never shows a state the component has left."""
        with self._lock:
            number, text = self._status_text[component]
        for client in list(self._clients):
            if client.dropped or client.status_seen.get(component, 0) >= number:
                continue
            if client.backlog >= client.depth:
                self._drop(client)
                continue
            client.status_seen[component] = number
            client.queue.put_nowait(text)
            self.frames_sent += 1

    def _drop(self, client: OutputClient) -> None:
        client.dropped = True
        self.dropped_clients += 1
        while not client.queue.empty():
            client.queue.get_nowait()
        client.latest.clear()
        client.queue.put_nowait(None)
        if client.on_drop is not None:
            client.on_drop()
        logger.warning("a UI client fell %d frames behind and was dropped", client.depth)

    # -- clients ------------------------------------------------------------------------------

    def connect(self, topics: Iterable[str] | None = None, binary: bool = False, full: bool = False) -> OutputClient:
        """A new client (on the event loop), following ``topics`` (None: every shown output); ``binary``:
        images as binary frames, latest-wins (see the module docstring); ``full``: those images at full
        resolution, not the preview size."""
        client = OutputClient(frozenset(topics) if topics is not None else None, self.client_queue, binary,
                              binary and full)
        self._clients.add(client)
        if binary:
            self._binary_clients += 1
            self._full_clients += client.full
        else:
            self._json_clients += 1
        with self._lock:
            known = list(self._status_text.items())
        for component, (number, text) in known[: client.depth]:  # the current status of each component, first
            client.status_seen[component] = number
            client.queue.put_nowait(text)
        return client

    def disconnect(self, client: OutputClient) -> None:
        if client in self._clients:
            self._clients.discard(client)
            if client.binary:
                self._binary_clients -= 1
                self._full_clients -= client.full
            else:
                self._json_clients -= 1

    @property
    def clients(self) -> list[OutputClient]:
        """The connected clients (a copy; read it on the event loop, or for diagnostics)."""
        return list(self._clients)

    @property
    def client_count(self) -> int:
        return len(self._clients)

    def latest_status(self, component: str) -> dict[str, Any] | None:
        """The last status frame seen for ``component``, or None."""
        with self._lock:
            return self._status.get(component)
