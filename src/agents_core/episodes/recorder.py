"""``EpisodeRecorder``: a recipe's topics cut into episodes, each an MCAP file and a JSON sidecar.

Values reach the recorder through :meth:`EpisodeRecorder.offer` (called inline on the middleware's
thread, by the :class:`~agents_core.episodes.component.EpisodeRecorderComponent`'s inputs or by
the subscriptions :meth:`EpisodeRecorder.attach` makes). Each one goes into the pre-buffer
(:class:`~agents_core.episodes.buffer.PreBuffer`: the last ``buffer_s`` seconds, at most
``buffer_bytes``), and, while an episode runs, into a queue (at most ``queue_bytes``; past it
new values are dropped and counted in the episode's ``dropped``) that one writer thread encodes
(:mod:`agents_core.recording.encodings`, the same forms ``agentsctl record`` writes) and writes
through :class:`~agents_core.recording.writer.McapSeriesWriter`.

An episode is:

- explicit: :meth:`~EpisodeRecorder.start_episode` then :meth:`~EpisodeRecorder.stop_episode`
  (an evaluation's episode, see :mod:`agents_core.episodes.hooks`);
- event-triggered: :meth:`~EpisodeRecorder.record_episode` ``(before_s, after_s)`` keeps the
  last ``before_s`` seconds from the pre-buffer and the next ``after_s`` seconds; a second event
  while it runs extends it.

An episode that passes ``max_episode_bytes`` (encoded) or ``max_episode_s`` is cut there, and its
sidecar says so (``ended``: ``"size_cap"`` / ``"duration_cap"``, with the ``reason``). Memory held
whatever the input rate: at most ``buffer_bytes + queue_bytes`` of values (the queue refers to the
same values as the ring), plus the writer's open chunk.

Files, in ``directory``: ``episode_000003.mcap`` and ``episode_000003.json``
(:class:`EpisodeInfo`); numbering continues after what the folder already holds.
"""

from __future__ import annotations

import collections
import json
import logging
import os
import re
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from attrs import asdict, define, field, validators

from ..errors import AgentsError, ConfigError
from ..recording.encodings import Encoding, Preference, encoding_for
from ..recording.writer import Compression, McapSeriesWriter, RecordingLimits, require_mcap
from ..topics import Topic
from .buffer import BufferedValue, PreBuffer, value_bytes

if TYPE_CHECKING:
    from typing import Self

    from ..transport.contract import Subscription, Transport
    from ..types.base import SupportedType

__all__ = ["EpisodeError", "EpisodeInfo", "EpisodeLimits", "EpisodeRecorder", "EpisodeRecorderStatistics",
           "load_episodes"]

logger = logging.getLogger(__name__)

#: The sidecar's format tag.
EPISODE_FORMAT = "agents_core.episode/1"
_NAME = re.compile(r"^episode_(\d{6,})\.(json|mcap)$")
_MiB = 2**20


_optional_positive: Any = validators.optional(validators.gt(0))


class EpisodeError(AgentsError, RuntimeError):
    """An episode request that cannot be done now (one already running, none running, recorder closed)."""


@define(frozen=True, kw_only=True)
class EpisodeLimits:
    """How much an episode recorder may hold and write.

    :param buffer_s: how many seconds the pre-buffer reaches back.
    :param buffer_bytes: the bytes (estimated) the pre-buffer may hold.
    :param queue_bytes: the bytes (estimated) waiting for the writer; past it new values are dropped.
    :param max_episode_bytes: cut an episode once its file would pass this (encoded bytes); None: no cap.
    :param max_episode_s: cut an episode after this many seconds; None: no cap.
    """

    buffer_s: float = field(default=10.0, validator=validators.ge(0))
    buffer_bytes: int = field(default=256 * _MiB, validator=validators.gt(0))
    queue_bytes: int = field(default=128 * _MiB, validator=validators.gt(0))
    max_episode_bytes: int | None = field(default=2048 * _MiB, validator=_optional_positive)
    max_episode_s: float | None = field(default=3600.0, validator=_optional_positive)


@define(kw_only=True)
class EpisodeInfo:
    """What an episode's JSON sidecar holds (``episode_000003.json`` beside ``episode_000003.mcap``).

    :param episode: the episode's number in its folder.
    :param mcap: the MCAP file (a path; relative to the sidecar's folder in the JSON).
    :param task: what the episode was about (LeRobot's task text).
    :param trigger: ``"explicit"`` (start/stop) or ``"event"`` (``record_episode``).
    :param started_ns: wall-clock time (ns) the episode's first kept value may have (pre-buffer included).
    :param ended_ns: wall-clock time (ns) it ended.
    :param ended: ``"stopped"``, ``"after_s"`` (an event's window passed), ``"size_cap"``,
        ``"duration_cap"`` or ``"closed"`` (the recorder closed while it ran).
    :param reason: why it was cut, in words (size and duration caps), else None.
    :param success: the outcome given to :meth:`EpisodeRecorder.stop_episode`, None if unknown.
    :param messages: values written.
    :param bytes: encoded bytes written.
    :param dropped: values the full queue gave up while it ran.
    :param topics: per topic: ``{"type": agents_core type name, "messages": n}``.
    :param extra: anything else given at start or stop (an evaluation's seed and result line).
    """

    episode: int
    mcap: Path
    task: str = ""
    trigger: Literal["explicit", "event"] = "explicit"
    started_ns: int = 0
    ended_ns: int = 0
    ended: str = "stopped"
    reason: str | None = None
    success: bool | None = None
    messages: int = 0
    bytes: int = 0
    dropped: int = 0
    topics: dict[str, dict[str, Any]] = field(factory=dict)
    extra: dict[str, Any] = field(factory=dict)

    @property
    def sidecar(self) -> Path:
        """The JSON file beside the MCAP file."""
        return self.mcap.with_suffix(".json")

    @property
    def duration_s(self) -> float:
        """Seconds from the start to the end."""
        return max(0.0, (self.ended_ns - self.started_ns) / 1e9)

    def to_json(self) -> dict[str, Any]:
        """The sidecar document."""
        doc = asdict(self, recurse=False)
        doc["mcap"] = self.mcap.name
        return {"format": EPISODE_FORMAT, **doc}

    @classmethod
    def from_json(cls, path: str | os.PathLike[str]) -> EpisodeInfo:
        """Read a sidecar (bounded: at most 16 MiB); ConfigError naming the file for a bad one."""
        path = Path(path)
        try:
            with open(path, "rb") as stream:
                raw = stream.read(16 * _MiB + 1)
            if len(raw) > 16 * _MiB:
                raise ValueError("larger than 16 MiB")
            doc = json.loads(raw)
            if not isinstance(doc, dict) or doc.get("format") != EPISODE_FORMAT:
                raise ValueError(f"not an episode sidecar (format {str(doc.get('format'))[:60]!r})"
                                 if isinstance(doc, dict) else "not a JSON object")
            doc.pop("format")
            mcap = path.parent / Path(str(doc.pop("mcap"))).name  # never outside the sidecar's folder
            _check_sidecar(doc)
            return cls(mcap=mcap, **doc)
        except (OSError, ValueError, TypeError, KeyError) as exc:
            raise ConfigError(f"episode sidecar {path}: {exc}") from None


#: The sidecar's fields and the types each may hold (a file is untrusted input: checked before use).
_SIDECAR_TYPES: dict[str, tuple[type, ...]] = {
    "episode": (int,), "task": (str,), "trigger": (str,), "started_ns": (int,), "ended_ns": (int,), "ended": (str,),
    "reason": (str, type(None)), "success": (bool, type(None)), "messages": (int,), "bytes": (int,),
    "dropped": (int,), "topics": (dict,), "extra": (dict,)}


def _check_sidecar(doc: dict[str, Any]) -> None:
    for name, value in doc.items():
        allowed = _SIDECAR_TYPES.get(name)
        if allowed is None:
            raise ValueError(f"unknown field {name[:60]!r}")
        if not isinstance(value, allowed) or (isinstance(value, bool) and bool not in allowed):
            raise ValueError(f"field {name!r} is a {type(value).__name__}")
    if doc.get("trigger", "explicit") not in ("explicit", "event"):
        raise ValueError(f"trigger {str(doc['trigger'])[:40]!r} is not 'explicit' nor 'event'")
    for topic, entry in doc.get("topics", {}).items():
        if not (isinstance(entry, dict) and isinstance(entry.get("type"), str)
                and isinstance(entry.get("messages"), int)):
            raise ValueError(f"topic {str(topic)[:60]!r}: expected {{'type': str, 'messages': int}}")


def load_episodes(directory: str | os.PathLike[str]) -> list[EpisodeInfo]:
    """The episodes recorded into ``directory`` (their sidecars), in episode order."""
    folder = Path(directory)
    if not folder.is_dir():
        raise ConfigError(f"no episodes folder {folder}")
    found = [EpisodeInfo.from_json(p) for p in sorted(folder.glob("episode_*.json")) if _NAME.match(p.name)]
    return sorted(found, key=lambda e: e.episode)


@define(frozen=True)
class EpisodeRecorderStatistics:
    """An episode recorder's counters.

    :param received: values offered.
    :param buffered: values in the pre-buffer now; ``buffered_bytes``: their estimated bytes.
    :param queued_bytes: estimated bytes waiting for the writer.
    :param evicted_for_bytes: values the pre-buffer gave up for its byte bound (not for age).
    :param episodes: episodes finished.
    :param recording: the running episode's number, None when none runs.
    :param errors: values that could not be encoded.
    """

    received: int
    buffered: int
    buffered_bytes: int
    queued_bytes: int
    evicted_for_bytes: int
    episodes: int
    recording: int | None
    errors: int


@define(eq=False)
class _Episode:
    info: EpisodeInfo
    deadline_ns: int | None = None
    open: bool = True
    writer: McapSeriesWriter | None = None
    done: threading.Event = field(factory=threading.Event)
    timer: threading.Timer | None = None


_Close = collections.namedtuple("_Close", "episode")


def _empty_mcap(path: Path) -> None:
    """An MCAP file with no message (an episode during which nothing arrived)."""
    mcap_writer = require_mcap()
    with open(path, "wb") as stream:
        writer = mcap_writer.Writer(stream)
        writer.start(profile="ros2", library="agents_core")
        writer.finish()


class EpisodeRecorder:
    """Records episodes of the values it is offered into ``directory`` (see the module docstring).

    :param directory: where episode files go (made if missing).
    :param limits: buffer and episode bounds (:class:`EpisodeLimits`).
    :param encoding: ``cdr`` (ROS 2 CDR where a type has a ROS form) or ``msgpack``.
    :param compression: each MCAP chunk's compression (``lz4``, ``zstd``, ``none``).
    :param name: for log lines and errors.
    """

    def __init__(self, directory: str | os.PathLike[str], *, limits: EpisodeLimits | None = None,
                 encoding: Preference = "cdr", compression: Compression = "lz4", name: str = "episodes") -> None:
        require_mcap()
        self.directory = Path(directory)
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ConfigError(f"{name}: cannot make the episodes folder {self.directory} ({exc})") from None
        self.limits = limits or EpisodeLimits()
        self.name = name
        self._prefer: Preference = encoding
        self._compression: Compression = compression
        self._buffer = PreBuffer(self.limits.buffer_bytes, self.limits.buffer_s)
        self._encodings: dict[tuple[str, str], Encoding | None] = {}
        self._lock = threading.Lock()
        self._cond = threading.Condition()
        self._queue: collections.deque[tuple[_Episode, BufferedValue] | _Close] = collections.deque()
        self._queued_bytes = 0
        self._active: _Episode | None = None
        self._next_index = self._first_free_index()
        self._received = 0
        self._errors = 0
        self._closed = False
        self._subscriptions: list[Subscription] = []
        #: The episodes finished so far, in order.
        self.episodes: list[EpisodeInfo] = []
        self._writer_thread = threading.Thread(target=self._write_loop, name=f"{name}-writer", daemon=True)
        self._writer_thread.start()

    def _first_free_index(self) -> int:
        used = [int(m.group(1)) for p in self.directory.iterdir() if (m := _NAME.match(p.name))]
        return max(used, default=-1) + 1

    # -- input ---------------------------------------------------------------------------------------

    def attach(self, transport: Transport, topics: Sequence[Topic]) -> Self:
        """Subscribe (inline) to ``topics`` on ``transport``; :meth:`close` unsubscribes."""
        for topic in topics:
            if not isinstance(topic, Topic):
                raise ConfigError(f"{self.name}: attach() takes Topic objects, got {type(topic).__name__}")
            self._subscriptions.append(transport.create_subscription(topic, self._offer_for(topic), inline=True))
        return self

    def _offer_for(self, topic: Topic) -> Callable[[Any], None]:
        def offer(value: Any) -> None:
            self.offer(topic.name, topic.msg_type, value)
        return offer

    def _encoding(self, topic: str, msg_type: type[SupportedType]) -> Encoding | None:
        key = (topic, msg_type.type_name())
        if key not in self._encodings:
            try:
                self._encodings[key] = encoding_for(msg_type, self._prefer)
            except ConfigError as exc:
                logger.warning("%s: not recording %r: %s", self.name, topic, exc)
                self._encodings[key] = None
        return self._encodings[key]

    def offer(self, topic: str, msg_type: type[SupportedType], value: Any) -> None:
        """Take one value of ``topic`` (never blocks: a full queue drops it and counts it)."""
        now = time.time_ns()
        encoding = self._encoding(topic, msg_type)
        if encoding is None or self._closed:
            return
        header = getattr(value, "header", None)
        stamp = getattr(header, "stamp_ns", 0)
        publish = stamp if isinstance(stamp, int) and 0 < stamp < 2**63 else now
        item = BufferedValue(topic, msg_type, encoding, value, now, publish, value_bytes(value))
        self._received += 1
        self._buffer.append(item)
        episode = self._active
        if episode is None:
            return
        cap = self.limits.max_episode_s
        if episode.deadline_ns is not None and now >= episode.deadline_ns:
            self._end(episode, "after_s", None)
        elif cap is not None and now - episode.info.started_ns > cap * 1e9:
            self._end(episode, "duration_cap", f"the episode passed max_episode_s={cap:g} s")
        else:
            self._enqueue(episode, item, bounded=True)

    def _enqueue(self, episode: _Episode, item: BufferedValue, *, bounded: bool) -> None:
        with self._cond:
            if bounded and self._queued_bytes + item.size > self.limits.queue_bytes:
                episode.info.dropped += 1
                return
            self._queue.append((episode, item))
            self._queued_bytes += item.size
            self._cond.notify()

    # -- episodes ------------------------------------------------------------------------------------

    def start_episode(self, task: str = "", *, before_s: float = 0.0, extra: Mapping[str, Any] | None = None,
                      _trigger: Literal["explicit", "event"] = "explicit",
                      _after_s: float | None = None) -> EpisodeInfo:
        """Start an episode now, keeping the last ``before_s`` seconds of the pre-buffer.

        Raises :class:`EpisodeError` if one is running (stop it first) or the recorder is closed.
        """
        if before_s < 0 or (_after_s is not None and _after_s < 0):
            raise ConfigError(f"{self.name}: before_s and after_s must not be negative")
        if before_s > self.limits.buffer_s:
            raise ConfigError(f"{self.name}: before_s={before_s:g} s is more than the pre-buffer holds "
                              f"(buffer_s={self.limits.buffer_s:g} s)")
        with self._lock:
            if self._closed:
                raise EpisodeError(f"{self.name}: the recorder is closed")
            if self._active is not None:
                raise EpisodeError(f"{self.name}: episode {self._active.info.episode} is still recording; "
                                   "stop it first")
            now = time.time_ns()
            start = now - int(before_s * 1e9)
            index, self._next_index = self._next_index, self._next_index + 1
            info = EpisodeInfo(episode=index, mcap=self.directory / f"episode_{index:06d}.mcap", task=str(task),
                               trigger=_trigger, started_ns=start, extra=dict(extra or {}))
            episode = _Episode(info, None if _after_s is None else now + int(_after_s * 1e9))
            # Under the ring's lock: a value arriving now is either in the ring's copy or sees the episode.
            with self._buffer.lock:
                for item in self._buffer.since_unlocked(start):
                    self._enqueue(episode, item, bounded=False)
                self._active = episode
            if _after_s is not None:
                self._arm_timer(episode, _after_s)
        logger.info("%s: episode %d started (%s)", self.name, index, _trigger)
        return info

    def _arm_timer(self, episode: _Episode, delay_s: float) -> None:
        if episode.timer is not None:
            episode.timer.cancel()
        episode.timer = threading.Timer(delay_s, self._end, (episode, "after_s", None))
        episode.timer.daemon = True
        episode.timer.start()

    def stop_episode(self, success: bool | None = None, *, extra: Mapping[str, Any] | None = None,
                     timeout: float = 60.0) -> EpisodeInfo:
        """End the running episode, wait (up to ``timeout`` s) until its file is written; returns its info.

        Raises :class:`EpisodeError` when no episode is running.
        """
        with self._lock:
            episode = self._active
            if episode is None:
                raise EpisodeError(f"{self.name}: no episode is recording")
            episode.info.success = success
            episode.info.extra.update(extra or {})
        self._end(episode, "stopped", None)
        if not episode.done.wait(timeout):
            logger.warning("%s: episode %d was not written within %.1f s", self.name, episode.info.episode, timeout)
        return episode.info

    def record_episode(self, before_s: float = 5.0, after_s: float = 5.0, task: str = "") -> EpisodeInfo:
        """Save the last ``before_s`` seconds and the next ``after_s`` seconds as one episode.

        An event while such an episode runs extends it to ``after_s`` from now; while an explicit
        episode runs, it is already being recorded and nothing changes.
        """
        with self._lock:
            episode = self._active
            if episode is not None:
                if episode.deadline_ns is not None:
                    episode.deadline_ns = max(episode.deadline_ns, time.time_ns() + int(after_s * 1e9))
                    self._arm_timer(episode, (episode.deadline_ns - time.time_ns()) / 1e9)
                return episode.info
        return self.start_episode(task, before_s=before_s, _trigger="event", _after_s=after_s)

    @property
    def recording(self) -> EpisodeInfo | None:
        """The running episode's info, None when none runs."""
        episode = self._active
        return episode.info if episode is not None else None

    def _end(self, episode: _Episode, ended: str, reason: str | None) -> None:
        """Close ``episode`` (once): no value joins it after this; the writer finishes its file."""
        with self._lock:
            if not episode.open:
                return
            episode.open = False
            if self._active is episode:
                self._active = None
            if episode.timer is not None:
                episode.timer.cancel()
            info = episode.info
            info.ended, info.reason = ended, reason
            info.ended_ns = min(time.time_ns(), episode.deadline_ns or 2**63)
        if reason:
            logger.warning("%s: episode %d cut: %s", self.name, info.episode, reason)
        with self._cond:
            self._queue.append(_Close(episode))
            self._cond.notify()

    # -- writing (the writer thread) -----------------------------------------------------------------

    def _write_loop(self) -> None:
        while True:
            with self._cond:
                while not self._queue:
                    if self._closed:
                        return
                    self._cond.wait(0.5)
                entry = self._queue.popleft()
                if not isinstance(entry, _Close):
                    self._queued_bytes -= entry[1].size
            try:
                if isinstance(entry, _Close):
                    self._finish(entry.episode)
                else:
                    self._write(*entry)
            except Exception as exc:  # one bad value or file must not end the writer
                self._errors += 1
                logger.warning("%s: %s", self.name, exc)

    def _write(self, episode: _Episode, item: BufferedValue) -> None:
        info = episode.info
        if info.reason is not None or (episode.done.is_set()):
            return  # cut: what was still queued for it is left out
        try:
            data = item.encoding.encode(item.value)
        except Exception as exc:
            self._errors += 1
            logger.warning("%s: a value on %r did not encode: %s", self.name, item.topic, exc)
            return
        cap = self.limits.max_episode_bytes
        if cap is not None and info.bytes + len(data) > cap:
            info.reason = (f"the episode reached max_episode_bytes={cap} ({info.bytes} bytes written; "
                           f"the next value on {item.topic!r} is {len(data)} bytes)")
            reason = info.reason
            self._end(episode, "size_cap", reason)
            info.ended, info.reason = "size_cap", reason  # also when it had been stopped already
            return
        if episode.writer is None:
            episode.writer = McapSeriesWriter(info.mcap, RecordingLimits(), compression=self._compression)
        if episode.writer.write(item.topic, item.msg_type.type_name(), item.encoding, data, item.log_time_ns,
                                item.publish_time_ns):
            info.messages += 1
            info.bytes += len(data)
            entry = info.topics.setdefault(item.topic, {"type": item.msg_type.type_name(), "messages": 0})
            entry["messages"] += 1

    def _finish(self, episode: _Episode) -> None:
        info = episode.info
        try:
            if episode.writer is None:  # nothing arrived: still an (empty) file, so the numbering holds
                _empty_mcap(info.mcap)
            else:
                episode.writer.close()
            tmp = info.sidecar.with_suffix(".json.tmp")
            tmp.write_text(json.dumps(info.to_json(), indent=1, default=str), encoding="utf-8")
            os.replace(tmp, info.sidecar)
            self.episodes.append(info)
            logger.info("%s: episode %d written: %d values, %d bytes, %s", self.name, info.episode, info.messages,
                        info.bytes, info.ended)
        finally:
            episode.writer = None
            episode.done.set()

    # -- state ---------------------------------------------------------------------------------------

    def statistics(self) -> EpisodeRecorderStatistics:
        """A snapshot of the counters (:class:`EpisodeRecorderStatistics`)."""
        active = self._active
        return EpisodeRecorderStatistics(
            received=self._received, buffered=len(self._buffer), buffered_bytes=self._buffer.bytes,
            queued_bytes=self._queued_bytes, evicted_for_bytes=self._buffer.evicted_for_bytes,
            episodes=len(self.episodes), recording=active.info.episode if active else None, errors=self._errors)

    def close(self, timeout: float = 30.0) -> None:
        """Unsubscribe, end a running episode (``ended="closed"``), write what is queued; idempotent."""
        for subscription in self._subscriptions:
            subscription.close()
        self._subscriptions.clear()
        active = self._active
        if active is not None:
            self._end(active, "closed", None)
            active.done.wait(timeout)
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        self._writer_thread.join(timeout)
        self._buffer.clear()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
