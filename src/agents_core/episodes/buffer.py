"""The pre-buffer: the last seconds of every recorded topic, bounded in bytes and in seconds.

An :class:`EpisodeRecorder <agents_core.episodes.recorder.EpisodeRecorder>` keeps what arrived
lately in a :class:`PreBuffer`, so that an event ("the gripper dropped the cube") can save the
seconds *before* it as well as those after. Each value is held as it arrived (no encoding on the
middleware's thread), together with its estimated size (:func:`value_bytes`). Two bounds apply
at every :meth:`PreBuffer.append`: values older than ``max_s`` seconds go, and the oldest go
while the total passes ``max_bytes``; one value larger than ``max_bytes`` is not kept at all.
Whatever the input rate, the buffer never holds more than ``max_bytes`` (estimated).
"""

from __future__ import annotations

import collections
import threading
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import attrs
from attrs import define

from ..support.lazy_numpy import np

if TYPE_CHECKING:
    from ..recording.encodings import Encoding
    from ..types.base import SupportedType

__all__ = ["BufferedValue", "PreBuffer", "value_bytes"]

#: What holding any value costs beyond its arrays and text (the Python objects around them).
_BASE_BYTES = 256


def value_bytes(value: Any, _depth: int = 0) -> int:
    """An estimate of the memory ``value`` holds: its arrays' bytes, its text, its nested messages.

    Walks the value's attrs fields (two levels: a message and the messages inside it, e.g. an
    RGBD's images), so a JointState's three arrays count as well as an Image's pixels.
    """
    if isinstance(value, np.ndarray):
        return int(value.nbytes)
    if isinstance(value, (bytes, bytearray, memoryview, str)):
        return len(value)
    size = _BASE_BYTES
    if _depth > 2:
        return size
    if attrs.has(type(value)):
        for field in attrs.fields(type(value)):
            part = getattr(value, field.name, None)
            if isinstance(part, (list, tuple)):
                size += sum(value_bytes(p, _depth + 1) for p in part[:10_000])
            elif part is not None and not isinstance(part, (int, float, bool)):
                size += value_bytes(part, _depth + 1)
    return size


@define(frozen=True)
class BufferedValue:
    """One value as it arrived: its topic, type and encoding, receipt and publish times (ns), its size."""

    topic: str
    msg_type: type[SupportedType]
    encoding: Encoding
    value: Any
    log_time_ns: int
    publish_time_ns: int
    size: int


class PreBuffer:
    """A ring of :class:`BufferedValue` holding at most ``max_bytes`` and ``max_s`` seconds (thread-safe).

    :param max_bytes: the estimated bytes the ring may hold.
    :param max_s: how far back (receipt time) the ring reaches.
    """

    def __init__(self, max_bytes: int, max_s: float) -> None:
        if max_bytes <= 0 or max_s < 0:
            raise ValueError("a pre-buffer needs max_bytes > 0 and max_s >= 0")
        self.max_bytes = max_bytes
        self.max_s = max_s
        self._items: collections.deque[BufferedValue] = collections.deque()
        self._bytes = 0
        self._lock = threading.RLock()
        #: Values evicted for the byte bound (not for age), and values too large to keep at all.
        self.evicted_for_bytes = 0
        self.too_large = 0

    @property
    def bytes(self) -> int:
        """The estimated bytes held now."""
        return self._bytes

    def __len__(self) -> int:
        return len(self._items)

    def append(self, item: BufferedValue) -> None:
        """Keep ``item``, then drop what is too old or past the byte bound."""
        with self._lock:
            if item.size > self.max_bytes:
                self.too_large += 1
            else:
                self._items.append(item)
                self._bytes += item.size
            self._trim(item.log_time_ns)

    def _trim(self, now_ns: int) -> None:
        oldest = now_ns - int(self.max_s * 1e9)
        items = self._items
        while items and items[0].log_time_ns < oldest:
            self._bytes -= items.popleft().size
        while items and self._bytes > self.max_bytes:
            self._bytes -= items.popleft().size
            self.evicted_for_bytes += 1

    @property
    def lock(self) -> threading.RLock:
        """The ring's lock (held by :meth:`append`): hold it to act on a snapshot before new values land."""
        return self._lock

    def since(self, start_ns: int) -> list[BufferedValue]:
        """The values received at or after ``start_ns``, oldest first (they stay in the ring)."""
        with self._lock:
            return self.since_unlocked(start_ns)

    def since_unlocked(self, start_ns: int) -> list[BufferedValue]:
        """:meth:`since` for a caller that holds :attr:`lock`."""
        return [item for item in self._items if item.log_time_ns >= start_ns]

    def clear(self) -> None:
        """Forget everything held."""
        with self._lock:
            self._items.clear()
            self._bytes = 0

    def __iter__(self) -> Iterator[BufferedValue]:
        with self._lock:
            return iter(list(self._items))
