"""How :class:`~agents_core.components.memory.Memory` buffers, checks and writes its observations.

Every observation is checked before it is buffered (:func:`problem_of`: a finite place and time, a text
that is valid Unicode and not longer than ``max_text_length``); one that fails is refused and counted
(``refused``). At write time each chunk is embedded in one request and committed in one transaction;
an embedding that is not a finite, non-zero vector refuses its observation alone, and a chunk the
database refuses for the data's sake is written again one observation at a time, so that the
observation at fault is dropped and counted and never holds back the ones after it. A failure of the
database itself (locked, disk full, I/O: :data:`~agents_core.components.memory.engine.TRANSIENT_ERRORS`)
keeps everything buffered for the next step, as a failed embedding request does.
"""

from __future__ import annotations

import collections
import itertools
import logging
import math
import threading
import time
from typing import TYPE_CHECKING, Any

from ...errors import ModelClientError
from .engine import TRANSIENT_ERRORS, MemoryStoreError, Observation, commit_batch

if TYPE_CHECKING:
    from .config import MemoryConfig
    from .engine import ClientEmbedder

__all__ = ["MemoryWriting", "problem_of"]

#: How many observations one embedding request carries at most.
EMBED_CHUNK = 64
#: The longest layer name (characters).
MAX_LAYER_NAME = 256


def problem_of(o: Observation, max_text: int) -> str | None:
    """Why observation ``o`` cannot be stored (None: it can)."""
    for name, value in (("x", o.x), ("y", o.y), ("z", o.z), ("time", o.stamp)):
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            return f"its {name} must be a finite number, got {value!r:.40}"
    if not isinstance(o.text, str) or not o.text.strip():
        return "its text is empty"
    if len(o.text) > max_text:
        return f"its text has {len(o.text)} characters (at most max_text_length={max_text})"
    if not isinstance(o.layer, str) or not o.layer or len(o.layer) > MAX_LAYER_NAME:
        return f"its layer name must be a text of 1 to {MAX_LAYER_NAME} characters"
    for what, text in (("text", o.text), ("layer name", o.layer)):
        try:
            text.encode("utf-8")
        except UnicodeEncodeError:
            return f"its {what} is not valid Unicode (it holds a lone surrogate)"
    return None


class MemoryWriting:
    """The buffer and the writes of a Memory (a mixin: the component holds the state named below)."""

    config: MemoryConfig
    component_name: str
    _logger: logging.Logger
    _lock: threading.Lock
    _engine_lock: threading.RLock
    _pending: collections.deque[Observation]
    _pending_since: float | None
    _counts: collections.Counter[str]
    _embedder: ClientEmbedder | None
    _engine: Any
    _index_saved: float

    def _open(self) -> Any:
        raise NotImplementedError

    def _count(self, what: str, n: int = 1) -> None:
        with self._lock:
            self._counts[what] += n

    def _enqueue(self, observation: Observation) -> str | None:
        """Buffer ``observation`` once checked; why it was refused (counted and logged) otherwise."""
        problem = problem_of(observation, self.config.max_text_length)
        if problem is not None:
            self._count("refused")
            self._logger.warning("layer %r: observation refused, not stored: %s", observation.layer[:80], problem)
            return problem
        with self._lock:
            if len(self._pending) >= self.config.buffer_size:
                self._pending.popleft()
                self._counts["dropped"] += 1
            if not self._pending:
                self._pending_since = time.monotonic()
            self._pending.append(observation)
        return None

    def _take(self, observations: list[Observation], *, stored: bool) -> None:
        """Take ``observations`` out of the buffer (stored, or refused)."""
        with self._lock:
            for observation in observations:
                if self._pending and self._pending[0] is observation:
                    self._pending.popleft()
                elif observation in self._pending:  # the oldest may have been dropped meanwhile
                    self._pending.remove(observation)
            self._counts["stored" if stored else "refused"] += len(observations)
            if not self._pending:  # else the rest keeps the older age: it never waits longer
                self._pending_since = None

    def _write(self, *, force: bool) -> int:
        """Embed and commit the buffered observations (when due, or ``force``); how many were written.

        Due by count, whole batches of ``flush_batch_size`` are written (the rest waits for its batch or
        for ``flush_interval``); forced or due by age, everything waiting now. Each chunk of up to
        ``EMBED_CHUNK`` is one embedding request and one transaction, and leaves the buffer, in order,
        only once committed (or refused: see the module docs); on a failure of the embedding server or
        of the database it stays for a retry and the typed error is raised.
        """
        with self._lock:
            waiting = len(self._pending)
            since = self._pending_since
        aged = since is not None and time.monotonic() - since >= self.config.flush_interval
        quota = waiting if force or aged else waiting - waiting % self.config.flush_batch_size
        if not quota:
            return 0
        written = done = 0
        with self._engine_lock:
            engine = self._open()
            assert self._embedder is not None
            while done < quota:
                with self._lock:
                    batch = list(itertools.islice(self._pending, min(EMBED_CHUNK, quota - done)))
                if not batch:
                    break
                try:
                    vectors = self._embedder.embed([o.text for o in batch])
                except ModelClientError:
                    self._count("embed_errors")
                    raise
                written += self._commit_checked(engine, batch, vectors)
                done += len(batch)
            if time.monotonic() - self._index_saved >= self.config.index_save_interval:
                self._save_index()
        return written

    def _commit_checked(self, engine: Any, batch: list[Observation], vectors: Any) -> int:
        """Commit ``batch``; observations the embedding or the database refuses are dropped and counted."""
        import numpy as np  # noqa: PLC0415

        usable = np.isfinite(vectors).all(axis=1) & (np.abs(vectors).sum(axis=1) > 0)
        if not usable.all():
            self._refuse([o for o, ok in zip(batch, usable, strict=True) if not ok],
                         "the embedding server returned a vector that is not finite and non-zero")
            batch, vectors = [o for o, ok in zip(batch, usable, strict=True) if ok], vectors[usable]
        if not batch:
            return 0
        try:
            self._commit(engine, batch, vectors)
        except _Refused as exc:
            if len(batch) == 1:
                self._refuse(batch, str(exc))
                return 0
            return sum(self._commit_checked(engine, [o], vectors[i:i + 1]) for i, o in enumerate(batch))
        self._take(batch, stored=True)
        return len(batch)

    def _refuse(self, observations: list[Observation], why: str) -> None:
        self._take(observations, stored=False)
        for o in observations:
            self._logger.warning("layer %r: observation refused by the store, dropped: %s", o.layer[:80], why)

    def _commit(self, engine: Any, batch: list[Observation], vectors: Any) -> None:
        try:
            commit_batch(engine, batch, vectors)
        except TRANSIENT_ERRORS as exc:
            self._count("store_errors")
            raise MemoryStoreError(f"cannot write to the memory database {self.config.db_path!r}: "
                                   f"{type(exc).__name__}: {exc}") from exc
        except Exception as exc:  # the data, not the database: the observation at fault is isolated
            raise _Refused(f"{type(exc).__name__}: {exc}") from exc

    def _save_index(self) -> None:
        with self._engine_lock:
            if self._engine is None:
                return
            try:
                self._engine.store.save()
                self._index_saved = time.monotonic()
            except (*TRANSIENT_ERRORS, RuntimeError) as exc:
                self._count("store_errors")
                self._logger.warning("the memory's vector index could not be saved: %s", exc)


class _Refused(Exception):
    """The database refused a batch for its data (not for a failure of its own)."""
