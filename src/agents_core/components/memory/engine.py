"""The bridge to the emem engine: our clients as its embedding provider and summariser, and opening it.

emem (``pip install 'agents-core[memory]'``) is imported here only, when a Memory configures: the
rest of the package, and ``import agents_core``, never load it.
"""

from __future__ import annotations

import contextlib
import functools
import json
import logging
import math
import os
import re
import sqlite3
from pathlib import Path
from typing import TYPE_CHECKING, Any

from attrs import define

from ...errors import ComponentError, ModelClientError
from ...support.install_hint import install_hint

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt

    from ...clients.model_base import ModelClient
    from .config import MemoryConfig

__all__ = ["TRANSIENT_ERRORS", "ClientEmbedder", "ClientSummarizer", "MemoryStoreError", "Observation", "commit_batch",
           "index_path", "open_engine", "require_emem"]

_logger = logging.getLogger(__name__)


class MemoryStoreError(ComponentError):
    """The memory's database or index cannot be opened or written (the observations stay buffered)."""


@define(frozen=True)
class Observation:
    """One observation waiting to be written: its text, place (m), time (Unix s), layer, and whether it is
    body state (an internal-state layer)."""

    text: str
    x: float
    y: float
    z: float
    stamp: float
    layer: str
    internal: bool


def require_emem() -> None:
    """Raise ImportError naming the extra when emem is not installed."""
    import importlib.util  # noqa: PLC0415

    if importlib.util.find_spec("emem") is None:
        raise ImportError(f"the Memory component needs the emem engine: {install_hint('memory')}")


def index_path(db_path: str) -> str:
    """Where the vector index of the database at ``db_path`` is kept."""
    return str(Path(db_path).with_suffix(".hnsw.bin"))


class ClientEmbedder:
    """emem's embedding provider made of one of our clients (``embed()``): errors stay our typed ones."""

    def __init__(self, client: ModelClient) -> None:
        self.client = client
        checkpoint = getattr(client, "model_init_params", {}).get("checkpoint")
        #: The embedding model's identity, kept with the database: its checkpoint (else its name).
        self.model = str(checkpoint or getattr(client, "model_name", "") or type(client).__name__)
        probe = client.embed(["dimension probe"])
        self._dim = len(probe[0])
        if self._dim < 1:
            raise ModelClientError(f"{type(client).__name__}: the embedding server returned an empty vector")

    @property
    def dim(self) -> int:
        """Length of the vectors."""
        return self._dim

    def embed(self, texts: list[str]) -> npt.NDArray[np.float32]:
        """One float32 row per text."""
        import numpy as np  # noqa: PLC0415

        if not texts:
            return np.empty((0, self._dim), dtype=np.float32)
        vectors = np.asarray(self.client.embed(list(texts)), dtype=np.float32)
        if vectors.ndim != 2 or vectors.shape[1] != self._dim:
            raise ModelClientError(f"{type(self.client).__name__}: embeddings of shape {vectors.shape}, "
                                   f"expected (n, {self._dim}) (did the embedding model change?)")
        return vectors


_SUMMARY = ("Below are observations a robot made, one per line. Write one or two plain sentences saying what was "
            "observed; keep names of objects, people and places. Do not add anything that is not there.\n\n{lines}")
_SYNTHESIS = ("Below are a robot's observations, grouped by the sensor stream they came from. Write a short paragraph "
              "saying what happened, combining the streams; keep names of objects, people and places; add nothing."
              "\n\n{groups}")
_ENTITIES = ("List the distinct things (objects, people, places) named in these observations of a robot, as a JSON "
             'array of objects with keys "name" (short, lower case), "entity_type" (object, person or place) and '
             '"confidence" (0 to 1). Answer with the JSON array only.\n\n{lines}')


class ClientSummarizer:
    """emem's consolidation summariser made of one of our model clients.

    A call that fails (server down, empty answer) falls back to joining the texts (and to no entities):
    consolidation never loses an episode because a model was unavailable; the failure is logged and counted.
    """

    def __init__(self, client: ModelClient, max_new_tokens: int = 256) -> None:
        self.client = client
        self.max_new_tokens = max_new_tokens
        self.failures = 0

    def _chat(self, prompt: str) -> str | None:
        try:
            result = self.client.inference({"query": [{"role": "user", "content": prompt}], "stream": False,
                                            "temperature": 0.2, "max_new_tokens": self.max_new_tokens})
        except ModelClientError as exc:
            self.failures += 1
            _logger.warning("consolidation model call failed (falling back to plain text): %s", exc)
            return None
        text = result.get("output")
        if not isinstance(text, str):
            self.failures += 1
            return None
        # Reasoning models wrap their thoughts in <think>; the summary is what follows.
        text = re.sub(r"<think>.*?</think>", "", text, flags=re.DOTALL).strip()
        return text or None

    def summarize(self, texts: list[str]) -> str:
        """One summary of ``texts``."""
        return self._chat(_SUMMARY.format(lines="\n".join(texts))) or " | ".join(texts)

    def synthesize(self, layer_texts: dict[str, list[str]]) -> str:
        """One summary of texts grouped by layer."""
        groups = "\n".join(f"[{layer}] " + " | ".join(texts) for layer, texts in sorted(layer_texts.items()))
        return self._chat(_SYNTHESIS.format(groups=groups)) or groups

    def extract_entities(self, texts: list[str]) -> list[dict[str, Any]]:
        """The things named in ``texts`` (``name``, ``entity_type``, ``confidence``); [] when unreadable."""
        answer = self._chat(_ENTITIES.format(lines="\n".join(texts)))
        match = re.search(r"\[.*\]", answer or "", re.DOTALL)
        if match is None:
            return []
        try:
            items = json.loads(match.group())
        except json.JSONDecodeError:
            return []
        found = []
        for item in items if isinstance(items, list) else []:
            if isinstance(item, dict) and isinstance(item.get("name"), str) and item["name"].strip():
                try:
                    confidence = min(max(float(item.get("confidence") or 1.0), 0.0), 1.0)
                except (TypeError, ValueError):
                    confidence = 1.0
                found.append({"name": item["name"].strip(), "entity_type": item.get("entity_type"),
                              "confidence": confidence})
        return found


@functools.cache
def _engine_class() -> Any:
    from emem import SpatioTemporalMemory  # noqa: PLC0415  (the optional engine)

    class CommittedMemory(SpatioTemporalMemory):  # type: ignore[misc]
        """emem's memory whose added observations wait in its working memory until :meth:`commit`."""

        #: The database's writer lock (:class:`~agents_core.components.memory.durable.DatabaseLock`).
        writer_lock: Any = None

        def commit(self) -> int:
            """Write the observations added since the last commit in one transaction; how many."""
            return int(self._wm.flush())

        def close(self) -> None:
            """Save, close, and let the next process open the database."""
            try:
                super().close()
            finally:
                if self.writer_lock is not None:
                    self.writer_lock.release()
                    self.writer_lock = None

    return CommittedMemory


def open_engine(config: MemoryConfig, embedder: ClientEmbedder,
                summarizer: ClientSummarizer | None) -> tuple[Any, list[str]]:
    """A ``SpatioTemporalMemory`` on ``config.db_path`` and what opening it did (for the log); MemoryStoreError
    when it cannot be opened.

    Its own batching is off: the component adds a batch of observations and calls ``commit()``
    (one SQLite transaction per batch), and takes them out of its buffer only once that returned.
    The database is checked, locked and marked first, and its index brought in line with its rows
    after (:mod:`~agents_core.components.memory.durable`).
    """
    from emem import SpatioTemporalMemoryConfig  # noqa: PLC0415  (the optional engine)

    from .durable import check_database_path, claim, resync, store_class  # noqa: PLC0415

    given = str(Path(config.db_path).expanduser())
    db_path = check_database_path(given, index_path(os.path.realpath(given)))
    hnsw_path = index_path(db_path)
    lock, notes = claim(db_path, hnsw_path, embedder.model, embedder.dim, config.on_embedding_change == "reembed")
    settings = SpatioTemporalMemoryConfig(
        db_path=db_path, hnsw_path=hnsw_path, embedding_dim=embedder.dim,
        # Never flushed by count or age on its own: a write that fails then loses nothing the component
        # has not kept in its own buffer, and a batch is one transaction instead of one per observation.
        flush_batch_size=2**62, flush_interval=math.inf, **config.engine_settings())
    engine: Any = None
    try:
        try:
            engine = _engine_class()(config=settings, embedding_provider=embedder, llm_client=summarizer)
        except RuntimeError as exc:  # hnswlib could not read the index file: rebuilt from the rows
            if not os.path.exists(hnsw_path):
                raise
            os.replace(hnsw_path, hnsw_path + ".damaged")
            notes.append(f"the vector index could not be read ({exc}): set aside as .damaged, rebuilt from the rows")
            engine = _engine_class()(config=settings, embedding_provider=embedder, llm_client=summarizer)
        engine.writer_lock = lock
        engine.store.__class__ = store_class()
        notes += resync(engine.store, embedder.embed)
    except BaseException as exc:
        if engine is not None:  # not closed through the engine: that would save an index not yet in line
            with contextlib.suppress(sqlite3.Error):
                engine.store._db.close()
        lock.release()
        if isinstance(exc, sqlite3.Error | OSError | RuntimeError):
            raise MemoryStoreError(f"cannot open the memory database {given!r}: {type(exc).__name__}: "
                                   f"{exc}") from exc
        raise
    return engine, notes


#: What a database refuses for reasons of its own (locked, disk full, I/O): the observations wait and are retried.
TRANSIENT_ERRORS = (sqlite3.OperationalError, OSError)


def commit_batch(engine: Any, batch: list[Observation], vectors: Any) -> None:
    """Add ``batch`` with its embeddings to an engine from :func:`open_engine` and commit it in one transaction.

    On any failure nothing of the batch is left anywhere (the transaction rolled back, its entries taken
    out of the engine's in-memory indexes) and the engine's error is raised as it is.
    """
    added: list[tuple[str, Observation]] = []
    try:
        for o, vector in zip(batch, vectors, strict=True):
            added.append((engine.add(text=o.text, x=o.x, y=o.y, z=o.z, timestamp=o.stamp, layer_name=o.layer,
                                     source_type="interoception" if o.internal else "perception",
                                     embedding=vector), o))
        engine.commit()
    except Exception:
        _undo(engine, added)
        raise


def _undo(engine: Any, added: list[tuple[str, Observation]]) -> None:
    store, ids = engine.store, {obs_id for obs_id, _ in added}
    with contextlib.suppress(sqlite3.Error):
        store._db.rollback()
    wm = engine._wm
    with wm._lock:
        wm._buffer.clear()
        kept = [o for o in wm._recent if o.id not in ids]
        wm._recent.clear()
        wm._recent.extend(kept)
    for obs_id, o in added:
        label = store._hnsw_str_map.pop(obs_id, None)
        if label is not None:
            store._hnsw_id_map.pop(label, None)
            with contextlib.suppress(RuntimeError):
                store._hnsw.mark_deleted(label)
        spatial = store._spatial
        number = spatial._str_to_int.pop(obs_id, None)
        if number is not None:
            spatial._int_to_str.pop(number, None)
            spatial._coords.pop(obs_id, None)
            with contextlib.suppress(Exception):
                spatial._index.delete(number, (o.x, o.y, o.z, o.x, o.y, o.z))
