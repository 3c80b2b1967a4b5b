"""``Player``: an MCAP recording published into a recipe on any transport.

At the recorded pace (``rate=1``), faster or slower (``rate=4``, ``rate=0.5``), as fast as
possible (``rate=None``), or one message at a time (:meth:`Player.step`). Topics can be renamed
(``remap={"camera": "front/camera"}``), chosen (``topics=``) and played again (``loop``). The
schedule follows the receipt times the recorder wrote (``log_time``); how late each message went
out against that schedule is kept, so :attr:`PlaybackStatistics.p99_lateness_s` says how faithful a
playback was.

The file is read ahead by at most one message (:func:`~agents_core.recording.reader.read_recording`),
so a recording of any length plays in constant memory.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from attrs import define, field

from ..errors import ConfigError
from ..topics import Topic
from ..transport.contract import Publisher, Transport
from .reader import DEFAULT_MAX_RECORD_BYTES, ReadSummary, RecordedMessage, read_recording

if TYPE_CHECKING:
    from typing import Self

__all__ = ["PlaybackStatistics", "Player"]

#: How many lateness samples are kept for the percentiles (the newest ones).
_MAX_SAMPLES = 100_000


@define
class PlaybackStatistics:
    """What a playback did: published, per-topic counts, lateness against the schedule, what reading found."""

    published: int = 0
    per_topic: dict[str, int] = field(factory=dict)
    lateness_s: list[float] = field(factory=list, repr=False)
    read: ReadSummary = field(factory=ReadSummary)

    def _percentile(self, q: float) -> float:
        if not self.lateness_s:
            return 0.0
        ordered = sorted(self.lateness_s)
        return ordered[min(len(ordered) - 1, int(q * len(ordered)))]

    @property
    def p50_lateness_s(self) -> float:
        """The median of how late messages went out against the recorded schedule (s)."""
        return self._percentile(0.5)

    @property
    def p99_lateness_s(self) -> float:
        """The 99th percentile of how late messages went out against the recorded schedule (s)."""
        return self._percentile(0.99)


class Player:
    """Publishes the messages of the recording ``path`` on ``transport`` (see the module docstring).

    :param transport: where to publish (a recipe's launcher transport on memory, or one of its own).
    :param path: the MCAP file.
    :param rate: playback speed against the recording; None: as fast as possible.
    :param remap: recorded topic name -> name to publish on.
    :param topics: only these recorded topics; None: all except the components' ``*/status``.
    :param loop: start again at the end (``play`` then stops on :meth:`stop`, or after ``max_loops``).
    :param max_record_bytes: the largest record the reader accepts (an untrusted file's limit).
    """

    def __init__(self, transport: Transport, path: str | Path, *, rate: float | None = 1.0,
                 remap: Mapping[str, str] | None = None, topics: Sequence[str] | None = None, loop: bool = False,
                 max_record_bytes: int = DEFAULT_MAX_RECORD_BYTES) -> None:
        if rate is not None and not rate > 0:
            raise ConfigError(f"rate must be positive (or None for as fast as possible), got {rate!r}")
        if not Path(path).is_file():
            raise ConfigError(f"recording {str(path)!r} is not a file")
        self._transport = transport
        self._path = Path(path)
        self._rate = rate
        self._remap = {k.lstrip("/"): v.lstrip("/") for k, v in (remap or {}).items()}
        self._topics = None if topics is None else {t.lstrip("/") for t in topics}
        self._loop = loop
        self._max_record_bytes = max_record_bytes
        self._publishers: dict[str, Publisher] = {}
        self._stop = threading.Event()
        self._stepper: Iterator[RecordedMessage] | None = None
        self.stats = PlaybackStatistics()

    def _messages(self) -> Iterator[RecordedMessage]:
        for message in read_recording(self._path, summary=self.stats.read, topics=self._topics,
                                      max_record_bytes=self._max_record_bytes):
            if self._topics is None and message.topic.endswith("/status"):
                continue  # a recipe's components publish their own status
            yield message

    def _publish(self, message: RecordedMessage) -> None:
        name = self._remap.get(message.topic, message.topic)
        publisher = self._publishers.get(name)
        if publisher is None:
            publisher = self._transport.create_publisher(Topic(name, message.msg_type))
            self._publishers[name] = publisher
        publisher.publish(message.value)
        self.stats.published += 1
        self.stats.per_topic[name] = self.stats.per_topic.get(name, 0) + 1

    def step(self) -> RecordedMessage | None:
        """Publish the next message (at once, whatever its time); None at the end of the recording."""
        if self._stepper is None:
            self._stepper = self._messages()
        message = next(self._stepper, None)
        if message is not None:
            self._publish(message)
        return message

    def play(self, *, max_loops: int | None = None) -> PlaybackStatistics:
        """Publish the recording on its schedule until its end (or :meth:`stop`); returns the statistics."""
        loops = 0
        while not self._stop.is_set():
            first_log: int | None = None
            started = time.monotonic()
            for message in self._messages():
                if self._stop.is_set():
                    break
                if self._rate is not None:
                    first_log = message.log_time_ns if first_log is None else first_log
                    due = started + max(0, message.log_time_ns - first_log) / 1e9 / self._rate
                    if self._stop.wait(max(0.0, due - time.monotonic())):
                        break
                    lateness = time.monotonic() - due
                    if len(self.stats.lateness_s) < _MAX_SAMPLES:
                        self.stats.lateness_s.append(lateness)
                self._publish(message)
            loops += 1
            if not self._loop or (max_loops is not None and loops >= max_loops) or self.stats.published == 0:
                break
        return self.stats

    def stop(self) -> None:
        """Make :meth:`play` return after the message it is on (from another thread or a signal handler)."""
        self._stop.set()

    def close(self) -> None:
        """Stop and close the publishers; idempotent."""
        self._stop.set()
        for publisher in self._publishers.values():
            publisher.close()
        self._publishers.clear()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
