"""``Recorder``: a running recipe's topics into MCAP, on any transport, never blocking the recipe.

The recorder is an ordinary subscriber of the :class:`~agents_core.transport.contract.Transport`
contract, so it records the same way on memory (give it the launcher's transport), Zenoh and ROS 2
(a transport of its own, in this process or another: ``agentsctl record``). It subscribes to:

- the topics it is given (a :class:`~agents_core.topics.Topic` is used as is; a bare name gets
  its type from discovery), or, with ``topics=None``, every topic discovery finds;
- each discovered component's status topic ``<name>/status`` (``include_status``).

Discovery runs again every ``discover_every_s`` while recording, so topics and components that
appear later are picked up (a transport without discovery records only the ``Topic`` objects given).

The path of one value: the middleware's thread calls the subscription inline, which stamps the
receipt time and puts the value into a bounded :class:`~agents_core.support.concurrency.DrainQueue`
(``queue_depth`` values, the newest dropped when full and counted, ``put`` never blocks); the
queue's thread encodes (:mod:`.encodings`) and writes (:mod:`.writer`). A flusher closes the
open chunk every ``flush_interval_s``, so a killed recorder loses at most that much.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from attrs import define

from ..errors import ConfigError, UnknownTypeError
from ..support.concurrency import DrainQueue
from ..topics import Topic
from ..transport.contract import Subscription, Transport
from ..transport.core import status_topic
from ..types.base import SupportedType, get_type
from .encodings import Encoding, Preference, encoding_for
from .writer import Compression, McapSeriesWriter, RecordingLimits

if TYPE_CHECKING:
    from typing import Self

__all__ = ["Recorder", "RecorderStatistics"]

logger = logging.getLogger(__name__)


@define(frozen=True)
class RecorderStatistics:
    """What a recorder did: every value received ends written, dropped, oversize, over_limit or an error.

    :param received: values the subscriptions handed over.
    :param written: values written to a file.
    :param dropped: values the full queue gave up (the writer fell behind: ``queue_depth`` or ``queue_bytes``).
    :param oversize: values larger than ``max_message_bytes``, skipped.
    :param over_limit: values that came after ``max_total_bytes`` / ``max_duration_s``.
    :param errors: values that could not be encoded.
    :param queued: values still waiting for the writer.
    :param topics: the topics being recorded.
    :param files: the files written so far.
    :param lost: values lost to failed writes (a full disk, a file size limit): written before the
        failure but after the last complete flush, or received while writing could not go on.
    :param write_failures: writes that failed (each outage is logged once, and once when it ends).
    """

    received: int
    written: int
    dropped: int
    oversize: int
    over_limit: int
    errors: int
    queued: int
    topics: list[str]
    files: list[Path]
    lost: int = 0
    write_failures: int = 0


_Item = tuple[str, type[SupportedType], Encoding, Any, int, int]


def approximate_bytes(value: Any) -> int:
    """A cheap estimate of what holding ``value`` costs: its arrays' bytes, its text, or a small constant."""
    size = 256
    for part in (value, getattr(value, "data", None), getattr(getattr(value, "image", None), "data", None)):
        nbytes = getattr(part, "nbytes", None)
        if isinstance(nbytes, int):
            size += nbytes
        elif isinstance(part, (str, bytes)):
            size += len(part)
    return size


class Recorder:
    """Records topics of ``transport`` into MCAP at ``path`` (see the module docstring).

    :param transport: the transport to subscribe on (the launcher's, on memory).
    :param path: the first file; later ones of a split series get ``_1``, ``_2``, ... before the suffix.
    :param topics: Topics or topic names to record; None: every topic discovery finds.
    :param include_status: also record each discovered component's ``<name>/status``.
    :param limits: size and duration limits (:class:`~agents_core.recording.writer.RecordingLimits`).
    :param queue_depth: values waiting for the writer before new ones are dropped.
    :param queue_bytes: the bytes those values may hold (arrays and text, estimated) before new ones are dropped.
    :param encoding: ``cdr`` (ROS 2 CDR where the type has a ROS form) or ``msgpack``.
    :param flush_interval_s: how often the open chunk is closed and flushed.
    :param discover_every_s: how often discovery looks for new topics and components.
    :param chunk_size: the bytes of a chunk before it is closed (and compressed).
    :param compression: each chunk's compression: ``lz4`` (the default: about half the CPU of ``zstd``, see
        ``docs/recording.md``), ``zstd`` (smaller files) or ``none``.

    Use as a context manager, or :meth:`start` then :meth:`stop`.
    """

    def __init__(self, transport: Transport, path: str | Path, *, topics: Sequence[Topic | str] | None = None,
                 include_status: bool = True, limits: RecordingLimits | None = None, queue_depth: int = 10_000,
                 queue_bytes: int = 256 * 2**20,
                 encoding: Preference = "cdr", flush_interval_s: float = 1.0, discover_every_s: float = 2.0,
                 chunk_size: int = 1024 * 1024, compression: Compression = "lz4") -> None:
        if flush_interval_s <= 0 or discover_every_s <= 0:
            raise ConfigError("flush_interval_s and discover_every_s must be positive")
        self._transport = transport
        self._wanted = list(topics) if topics is not None else None
        self._include_status = include_status
        self._prefer: Preference = encoding
        self._flush_interval = flush_interval_s
        self._discover_every = discover_every_s
        self._writer = McapSeriesWriter(path, limits or RecordingLimits(), chunk_size=chunk_size,
                                          compression=compression)
        self._queue: DrainQueue[_Item] = DrainQueue(self._write, depth=queue_depth, policy="drop_newest",
                                                    name="recorder-writer")
        self._subscriptions: dict[str, Subscription] = {}
        self._queue_bytes_limit = queue_bytes
        self._queued_bytes = 0
        self._dropped_for_bytes = 0
        self._bytes_lock = threading.Lock()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._errors = 0
        self._threads: list[threading.Thread] = []
        self._started = False

    # -- lifecycle -----------------------------------------------------------------------------------

    def start(self) -> Self:
        """Subscribe to what can be subscribed now, then keep discovering and flushing until :meth:`stop`."""
        if self._started:
            return self
        self._started = True
        for topic in self._wanted or []:
            if isinstance(topic, Topic):
                self._subscribe(topic)
        self._discover_once()
        for target, name in ((self._flush_loop, "recorder-flush"), (self._discover_loop, "recorder-discover")):
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)
        return self

    def stop(self, timeout: float = 10.0) -> RecorderStatistics:
        """Unsubscribe, write what is queued (up to ``timeout`` s), finish the file; returns the statistics."""
        self._stop.set()
        with self._lock:
            subscriptions = list(self._subscriptions.values())
        for subscription in subscriptions:
            subscription.close()
        self._queue.stop(discard=False)
        if not self._queue.join(timeout):
            logger.warning("recorder: the writer did not finish within %.1f s; the file ends early", timeout)
        for thread in self._threads:
            thread.join(timeout=2.0)
        self._writer.close()
        return self.statistics()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def statistics(self) -> RecorderStatistics:
        """A snapshot of the counters (see :class:`RecorderStatistics`)."""
        q = self._queue.statistics()
        with self._lock:
            topics = sorted(self._subscriptions)
        w = self._writer
        with self._bytes_lock:
            dropped = q.dropped + self._dropped_for_bytes
        return RecorderStatistics(received=q.offered + self._dropped_for_bytes, written=w.written, dropped=dropped,
                                  oversize=w.oversize,
                                  over_limit=w.over_limit, errors=self._errors + q.errors, queued=q.queued,
                                  topics=topics, files=list(w.files), lost=w.lost, write_failures=w.write_failures)

    # -- subscribing ---------------------------------------------------------------------------------

    def _subscribe(self, topic: Topic) -> None:
        name = topic.name
        with self._lock:
            if name in self._subscriptions or self._stop.is_set():
                return
        msg_type = topic.msg_type
        try:
            encoding = encoding_for(msg_type, self._prefer)
        except ConfigError as exc:
            logger.warning("recorder: not recording %r: %s", name, exc)
            return

        def offer(value: Any, _name: str = name, _type: type[SupportedType] = msg_type,
                  _encoding: Encoding = encoding) -> None:
            size = approximate_bytes(value)
            with self._bytes_lock:
                if self._queued_bytes + size > self._queue_bytes_limit:
                    self._dropped_for_bytes += 1
                    return
                self._queued_bytes += size
            if not self._queue.put((_name, _type, _encoding, value, time.time_ns(), size)):
                with self._bytes_lock:
                    self._queued_bytes -= size

        subscription = self._transport.create_subscription(topic, offer, inline=True)
        with self._lock:
            self._subscriptions[name] = subscription

    def _discover_once(self) -> None:
        if not self._transport.capabilities.discovery:
            return
        try:
            graph = self._transport.discover(timeout=min(1.0, self._transport.capabilities.discovery_settle_s))
        except Exception as exc:  # a graph query that fails now may work on the next round
            logger.debug("recorder: discovery failed: %s", exc)
            return
        wanted_names = None if self._wanted is None else {t if isinstance(t, str) else t.name for t in self._wanted}
        for info in graph.topics:
            if info.name.endswith("/status") or (wanted_names is not None and info.name not in wanted_names):
                continue
            try:
                self._subscribe(Topic(info.name, get_type(info.msg_type)))
            except UnknownTypeError:
                continue  # a plain ROS topic whose type has no agents_core form
        if self._include_status:
            for component in graph.components:
                self._subscribe(status_topic(component))

    def _discover_loop(self) -> None:
        while not self._stop.wait(self._discover_every):
            self._discover_once()

    def _flush_loop(self) -> None:
        while not self._stop.wait(self._flush_interval):
            try:
                self._writer.flush()  # a failed write is handled (and counted) by the writer itself
            except Exception:  # anything else: this thread must go on flushing
                logger.exception("recorder: flushing failed")

    # -- writing (the queue's thread) ----------------------------------------------------------------

    def _write(self, item: _Item) -> None:
        name, msg_type, encoding, value, log_time, size = item
        try:
            data = encoding.encode(value)
        except Exception as exc:  # one value that does not encode must not end the recording
            self._errors += 1
            logger.warning("recorder: a value on %r did not encode: %s", name, exc)
            return
        finally:
            with self._bytes_lock:
                self._queued_bytes -= size
        header = getattr(value, "header", None)
        stamp = getattr(header, "stamp_ns", 0)
        publish_time = stamp if isinstance(stamp, int) and 0 < stamp < 2**63 else log_time
        self._writer.write(name, msg_type.type_name(), encoding, data, log_time, publish_time)
