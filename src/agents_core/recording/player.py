"""``Player``: an MCAP recording published into a recipe on any transport.

At the recorded pace (``rate=1``), faster or slower (``rate=4``, ``rate=0.5``), as fast as
possible (``rate=None``), or one message at a time (:meth:`Player.step`). Topics can be renamed
(``remap={"camera": "front/camera"}``), chosen (``topics=``) and played again (``loop``). The
schedule follows the receipt times the recorder wrote (``log_time``); how late each message went
out against that schedule is kept, so :attr:`PlaybackStatistics.p99_lateness_s` says how faithful a
playback was.

A recorded channel whose type conflicts with the live recipe's topic of that name (or that the
transport refuses) is skipped and counted (:attr:`PlaybackStatistics.skipped_topics`), not the
end of the playback. A time that no schedule can honour (past year 2262, i.e. not below 2**63
ns) is refused and counted (``bad_timestamps``); a jump of more than ``max_gap_s`` between two
messages is not waited for: the schedule starts again at that message (``time_jumps``).

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

from ..errors import AgentsError, ConfigError
from ..topics import Topic
from ..transport.contract import Publisher, Transport
from .reader import DEFAULT_MAX_RECORD_BYTES, ReadSummary, RecordedMessage, read_recording

if TYPE_CHECKING:
    from typing import Self

__all__ = ["PlaybackStatistics", "Player"]

#: How many lateness samples are kept for the percentiles (the newest ones).
_MAX_SAMPLES = 100_000
#: Topics named in :attr:`PlaybackStatistics.skipped_topics` (the rest only counted).
_MAX_SKIPPED_TOPICS = 100
#: The latest time a message may carry: nanoseconds below 2**63 (year 2262).
_MAX_TIME_NS = 2**63 - 1
#: The longest single wait (a very slow ``rate`` times ``max_gap_s`` must not overflow a timeout).
_LONGEST_WAIT_S = 1e8


@define
class PlaybackStatistics:
    """What a playback did: published, per-topic counts, lateness against the schedule, what reading found."""

    published: int = 0
    per_topic: dict[str, int] = field(factory=dict)
    lateness_s: list[float] = field(factory=list, repr=False)
    read: ReadSummary = field(factory=ReadSummary)
    #: Topics not published, with the reason (a type conflicting with the live recipe's), the first 100.
    skipped_topics: dict[str, str] = field(factory=dict)
    #: Messages not published because their topic was skipped.
    skipped_messages: int = 0
    #: Messages refused for a time no schedule can honour (not below 2**63 ns).
    bad_timestamps: int = 0
    #: Jumps of more than ``max_gap_s`` between messages, where the schedule started again.
    time_jumps: int = 0

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
    :param max_gap_s: the longest wait between two messages on the schedule (recorded time, before
        ``rate``); a longer gap is a jump: the schedule starts again at that message, counted.
    """

    def __init__(self, transport: Transport, path: str | Path, *, rate: float | None = 1.0,
                 remap: Mapping[str, str] | None = None, topics: Sequence[str] | None = None, loop: bool = False,
                 max_record_bytes: int = DEFAULT_MAX_RECORD_BYTES, max_gap_s: float = 3600.0) -> None:
        if not max_gap_s > 0 or max_gap_s > 10 * 365 * 86400:
            raise ConfigError(f"max_gap_s must be positive and at most ten years, got {max_gap_s!r}")
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
        self._max_gap_ns = int(max_gap_s * 1e9)
        self._skipped: set[str] = set()
        self._publishers: dict[str, Publisher] = {}
        self._stop = threading.Event()
        self._stepper: Iterator[RecordedMessage] | None = None
        self.stats = PlaybackStatistics()

    def _messages(self) -> Iterator[RecordedMessage]:
        for message in read_recording(self._path, summary=self.stats.read, topics=self._topics,
                                      max_record_bytes=self._max_record_bytes):
            if self._topics is None and message.topic.endswith("/status"):
                continue  # a recipe's components publish their own status
            if not 0 <= message.log_time_ns <= _MAX_TIME_NS:
                self.stats.bad_timestamps += 1
                continue
            yield message

    def _publish(self, message: RecordedMessage) -> None:
        name = self._remap.get(message.topic, message.topic)
        publisher = self._publishers.get(name)
        if publisher is None:
            if name in self._skipped:
                self.stats.skipped_messages += 1
                return
            try:
                publisher = self._transport.create_publisher(Topic(name, message.msg_type))
            except (AgentsError, ValueError) as exc:  # the live recipe's topic has another type
                self._skipped.add(name)
                if len(self.stats.skipped_topics) < _MAX_SKIPPED_TOPICS:
                    self.stats.skipped_topics[name] = str(exc)[:500]
                self.stats.skipped_messages += 1
                return
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
            last_log = 0
            started = time.monotonic()
            for message in self._messages():
                if self._stop.is_set():
                    break
                if self._rate is not None:
                    if first_log is not None and message.log_time_ns - last_log > self._max_gap_ns:
                        # A jump no schedule should wait for (a clock reset, a hostile file): start again here.
                        self.stats.time_jumps += 1
                        first_log, started = None, time.monotonic()
                    first_log = message.log_time_ns if first_log is None else first_log
                    last_log = max(last_log, message.log_time_ns)
                    due = started + max(0, message.log_time_ns - first_log) / 1e9 / self._rate
                    if self._stop.wait(min(max(0.0, due - time.monotonic()), _LONGEST_WAIT_S)):
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
