"""``MemoryConfig``: the settings of the :class:`~agents_core.components.memory.Memory` component.

Kept in the memory package (``agents_core.config`` re-exports it lazily) so that the configs
module stays one concept of a reasonable size and never imports the memory component.
"""

from __future__ import annotations

from typing import Any

import attrs
from attrs import define, field

from ... import base_validators
from ...config import AT_CONFIGURE, BaseComponentConfig
from ...errors import ConfigError

__all__ = ["MemoryConfig"]


def _db_path(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    if not isinstance(value, str) or not value.strip():
        raise ConfigError(f"MemoryConfig.db_path must be a non-empty path, got {value!r}")


@define(kw_only=True)
class MemoryConfig(BaseComponentConfig):
    """Settings of the :class:`~agents_core.components.memory.Memory` component.

    Where and how observations are kept:

    :param db_path: the SQLite file of the memory; the vector index lives beside it
        (``<db_path without suffix>.hnsw.bin``), and the writer lock (``<db_path>.lock``). What was
        committed survives a restart of the component or process, a crash included. A path that is not
        a regular file, or a file that is not a Memory database, is refused untouched.
    :param auto_store: take a snapshot of the layers at every step (False: only the ``store`` action does).
    :param position_timeout: a snapshot is only stored when the robot's position arrived at most this many
        seconds before; older (or no) position: the layer values are not stored, and counted.
    :param cell_size: the grain (m) at which a layer without ``temporal_change`` recognises "the same value
        at the same place" (multiplied by the layer's ``resolution_multiple``).
    :param buffer_size: the most observations held while they cannot be written (embedding server down,
        database not writable); when full the oldest is dropped and counted.
    :param flush_batch_size: write (and embed, in one request) once this many observations wait, in whole
        batches of this size (a backlog goes in requests and transactions of up to 64) ...
    :param flush_interval: ... or once the oldest waiting one is this many seconds old.
    :param index_save_interval: how often (s) the vector index file is saved while writing (it is always
        saved at deactivate and shutdown); the database rows are committed at once.
    :param max_text_length: the longest observation text (characters); a longer value is refused and counted.
    :param on_embedding_change: a database written with another embedding model (checkpoint or dimension):
        ``"refuse"`` it (the default: the Memory stays unopened, its health says why) or ``"reembed"`` every
        stored text with the new model at open (logged).
    :param embedding_checkpoint: accepted for upstream recipes and unused: Memory never downloads a model,
        its embeddings come from the ``embedding_client`` the recipe gives.

    Passed to the emem engine as they are (same names and meaning as ``emem.SpatioTemporalMemoryConfig``):
    ``working_memory_size``, ``consolidation_window``, ``consolidation_spatial_eps``,
    ``consolidation_min_samples``, ``archive_after_seconds``, ``entity_extract_flush_interval``,
    ``entity_extract_time_interval``, ``entity_similarity_threshold``, ``entity_spatial_radius``,
    ``recency_weight``, ``recency_halflife``, ``hnsw_ef_construction``, ``hnsw_m``, ``hnsw_ef_search``,
    ``hnsw_max_elements``.
    """

    db_path: str = field(default="memory.db", validator=_db_path, metadata=AT_CONFIGURE)
    auto_store: bool = field(default=True)
    position_timeout: float = field(default=2.0, validator=base_validators.gt(0.0))
    cell_size: float = field(default=1.0, validator=base_validators.gt(0.0))
    buffer_size: int = field(default=1000, validator=base_validators.in_range(1, 10_000_000))
    flush_batch_size: int = field(default=5, validator=base_validators.in_range(1, 100_000))
    flush_interval: float = field(default=2.0, validator=base_validators.ge(0.0))
    index_save_interval: float = field(default=10.0, validator=base_validators.gt(0.0))
    max_text_length: int = field(default=16_384, validator=base_validators.in_range(1, 10_000_000))
    on_embedding_change: str = field(default="refuse", validator=base_validators.in_(("refuse", "reembed")),
                                     metadata=AT_CONFIGURE)
    embedding_checkpoint: str | None = field(default=None)
    # The emem engine's own settings (read at configure).
    working_memory_size: int = field(default=50, validator=base_validators.gt(0), metadata=AT_CONFIGURE)
    consolidation_window: float = field(default=1800.0, validator=base_validators.gt(0.0), metadata=AT_CONFIGURE)
    consolidation_spatial_eps: float = field(default=3.0, validator=base_validators.gt(0.0), metadata=AT_CONFIGURE)
    consolidation_min_samples: int = field(default=3, validator=base_validators.gt(0), metadata=AT_CONFIGURE)
    archive_after_seconds: float = field(default=3600.0, validator=base_validators.gt(0.0), metadata=AT_CONFIGURE)
    entity_extract_flush_interval: int = field(default=10, validator=base_validators.gt(0),
                                               metadata=AT_CONFIGURE)
    entity_extract_time_interval: float = field(default=60.0, validator=base_validators.gt(0.0),
                                                metadata=AT_CONFIGURE)
    entity_similarity_threshold: float = field(default=0.85, validator=base_validators.in_range(0.0, 1.0),
                                               metadata=AT_CONFIGURE)
    entity_spatial_radius: float = field(default=5.0, validator=base_validators.gt(0.0), metadata=AT_CONFIGURE)
    recency_weight: float = field(default=0.0, validator=base_validators.in_range(0.0, 1.0), metadata=AT_CONFIGURE)
    recency_halflife: float = field(default=3600.0, validator=base_validators.gt(0.0), metadata=AT_CONFIGURE)
    hnsw_ef_construction: int = field(default=200, validator=base_validators.gt(0), metadata=AT_CONFIGURE)
    hnsw_m: int = field(default=16, validator=base_validators.gt(0), metadata=AT_CONFIGURE)
    hnsw_ef_search: int = field(default=50, validator=base_validators.gt(0), metadata=AT_CONFIGURE)
    hnsw_max_elements: int = field(default=100_000, validator=base_validators.gt(0), metadata=AT_CONFIGURE)

    def engine_settings(self) -> dict[str, Any]:
        """The fields handed to ``emem.SpatioTemporalMemoryConfig`` unchanged."""
        names = ("working_memory_size", "consolidation_window", "consolidation_spatial_eps",
                 "consolidation_min_samples", "archive_after_seconds", "entity_extract_flush_interval",
                 "entity_extract_time_interval", "entity_similarity_threshold", "entity_spatial_radius",
                 "recency_weight", "recency_halflife", "hnsw_ef_construction", "hnsw_m", "hnsw_ef_search",
                 "hnsw_max_elements")
        return {name: getattr(self, name) for name in names}
