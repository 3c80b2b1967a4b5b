"""The bridge to the emem engine: our clients as its embedding provider and summariser, and opening it.

emem (``pip install 'agents-core[memory]'``) is imported here only, when a Memory configures: the
rest of the package, and ``import agents_core``, never load it.
"""

from __future__ import annotations

import functools
import json
import logging
import math
import re
import sqlite3
from pathlib import Path
from typing import TYPE_CHECKING, Any

from attrs import define

from ...errors import ComponentError, ModelClientError
from ...install_hint import install_hint

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt

    from ...clients.model_base import ModelClient
    from .config import MemoryConfig

__all__ = ["ClientEmbedder", "ClientSummarizer", "MemoryStoreError", "Observation", "commit_batch", "index_path",
           "open_engine", "require_emem"]

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

        def commit(self) -> int:
            """Write the observations added since the last commit in one transaction; how many."""
            return int(self._wm.flush())

    return CommittedMemory


def open_engine(config: MemoryConfig, embedder: ClientEmbedder, summarizer: ClientSummarizer | None) -> Any:
    """A ``SpatioTemporalMemory`` on ``config.db_path``; MemoryStoreError when it cannot be opened.

    Its own batching is off: the component adds a batch of observations and calls ``commit()``
    (one SQLite transaction per batch), and takes them out of its buffer only once that returned.
    """
    from emem import SpatioTemporalMemoryConfig  # noqa: PLC0415  (the optional engine)

    db_path = str(Path(config.db_path).expanduser())
    settings = SpatioTemporalMemoryConfig(
        db_path=db_path, hnsw_path=index_path(db_path), embedding_dim=embedder.dim,
        # Never flushed by count or age on its own: a write that fails then loses nothing the component
        # has not kept in its own buffer, and a batch is one transaction instead of one per observation.
        flush_batch_size=2**62, flush_interval=math.inf, **config.engine_settings())
    try:
        return _engine_class()(config=settings, embedding_provider=embedder, llm_client=summarizer)
    except (sqlite3.Error, OSError, RuntimeError) as exc:
        raise MemoryStoreError(f"cannot open the memory database {db_path!r}: {type(exc).__name__}: {exc}") from exc


def commit_batch(engine: Any, batch: list[Observation], vectors: Any) -> None:
    """Add ``batch`` with its embeddings to an engine from :func:`open_engine` and commit it in one transaction
    (the engine's errors are raised as they are)."""
    for o, vector in zip(batch, vectors, strict=True):
        engine.add(text=o.text, x=o.x, y=o.y, z=o.z, timestamp=o.stamp, layer_name=o.layer,
                   source_type="interoception" if o.internal else "perception", embedding=vector)
    engine.commit()
