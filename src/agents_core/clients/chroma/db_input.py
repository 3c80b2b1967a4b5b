"""The ``db_input`` dicts of :class:`~agents_core.clients.chroma.ChromaClient`, checked, and its answers read back.

Every operation also takes ``"collection_name"`` (default: the
:class:`~agents_core.vectordbs.ChromaDB`'s ``collection_name``). Unknown keys are refused, so a
typo such as ``"metadata"`` for ``"metadatas"`` is a :class:`~agents_core.errors.ConfigError`
rather than silently lost data.

``add``::

    {"ids": [str, ...],                  # required, unique
     "documents": [str, ...],            # required, one per id
     "metadatas": [dict | None, ...],    # optional, one per id
     "embeddings": [[float, ...], ...],  # optional: skip the embedding client
     "mode": "upsert" | "add",           # default "upsert"; "add" leaves existing ids untouched
     "distance_func": "l2" | "cosine" | "ip",  # for a collection created by this call
     "reset_collection": bool}           # delete the collection first (default False)
    -> {"collection_name": str, "mode": str, "ids": [str, ...]}

Chroma merges metadata on upsert and update: the given keys are set, keys not given are kept.

``conditional_add`` takes the keys of ``add`` but ``mode`` and ``reset_collection``, plus
``"update_metadatas": bool`` (default True). Ids already in the collection keep their document and
vector (they are not embedded again); the given metadata is merged into theirs unless
``update_metadatas`` is False (upstream semantics). The other ids are added::

    -> {"collection_name": str, "added": [str, ...], "skipped": [str, ...],
        "updated_metadatas": [str, ...]}

``query`` (nearest neighbours of one text)::

    {"query": str,                       # or "embedding": [float, ...]
     "n_results": int,                   # default 10
     "where": dict}                      # optional Chroma metadata filter
    -> {"collection_name": str, "ids": [...], "documents": [...], "metadatas": [...],
        "distances": [...]}              # nearest first; empty lists on an empty collection

``metadata_query``::

    {"where": dict,                      # a Chroma filter, e.g. {"room": "hall"} or
                                         # {"$and": [{"floor": {"$gte": 1}}, {"room": "hall"}]}
     "metadatas": [dict, ...],           # or: records matching any dict (all its keys equal)
     "limit": int}                       # optional
    -> {"collection_name": str, "ids": [...], "documents": [...], "metadatas": [...]}

A ``where`` with several plain keys (``{"room": "hall", "floor": 1}``) is sent as their ``$and``,
which Chroma requires. Records stored without metadata come back with ``None``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from ...errors import ConfigError, ProtocolError

__all__ = ["ADD_KEYS", "CONDITIONAL_ADD_KEYS", "METADATA_QUERY_KEYS", "MODES", "QUERY_KEYS", "SPACES", "answer_column",
           "check_distance", "check_flag", "check_keys", "check_records", "check_vector", "check_where",
           "where_from_metadatas"]

#: The distance functions a collection may be created with.
SPACES = ("l2", "cosine", "ip")
#: How ``add`` writes: ``"upsert"`` replaces existing ids, ``"add"`` leaves them untouched.
MODES = ("upsert", "add")

#: The keys each operation accepts.
ADD_KEYS = frozenset({"ids", "documents", "metadatas", "embeddings", "collection_name", "distance_func",
                      "mode", "reset_collection"})
CONDITIONAL_ADD_KEYS = frozenset({"ids", "documents", "metadatas", "embeddings", "collection_name",
                                  "distance_func", "update_metadatas"})
QUERY_KEYS = frozenset({"query", "embedding", "n_results", "where", "collection_name"})
METADATA_QUERY_KEYS = frozenset({"where", "metadatas", "limit", "collection_name"})


def check_keys(operation: str, db_input: Any, allowed: frozenset[str]) -> None:
    """ConfigError unless ``db_input`` is a dict whose keys are all ``allowed``."""
    if not isinstance(db_input, dict):
        raise ConfigError(f"{operation}: db_input must be a dict, got {type(db_input).__name__}")
    unknown = sorted(set(db_input) - allowed)
    if unknown:
        raise ConfigError(f"{operation}: unknown db_input key(s) {unknown}; known: {sorted(allowed)}")


def check_flag(db_input: dict[str, Any], key: str, default: bool) -> bool:
    """``db_input[key]`` (``default`` when absent), which must be a bool."""
    value = db_input.get(key, default)
    if not isinstance(value, bool):
        raise ConfigError(f"db_input[{key!r}] must be a bool, got {value!r}")
    return value


def check_distance(db_input: dict[str, Any]) -> str | None:
    """``db_input["distance_func"]``: one of :data:`SPACES`, or None when absent."""
    value = db_input.get("distance_func")
    if value is not None and value not in SPACES:
        raise ConfigError(f"db_input['distance_func'] must be one of {list(SPACES)}, got {value!r}")
    return value


def _str_list(db_input: dict[str, Any], key: str) -> list[str]:
    if db_input.get(key) is None:
        raise ConfigError(f"db_input lacks {key!r} (a list of str)")
    value = db_input[key]
    if isinstance(value, str) or not isinstance(value, Sequence) or not all(isinstance(v, str) for v in value):
        raise ConfigError(f"db_input[{key!r}] must be a list of str, got {value!r:.200}")
    return list(value)


def check_records(db_input: dict[str, Any]) -> tuple[list[str], list[str], list[Any] | None, list[list[float]] | None]:
    """ids, documents, metadatas and vectors of an add, checked for shape (lengths, types, unique ids)."""
    ids = _str_list(db_input, "ids")
    documents = _str_list(db_input, "documents")
    if len(documents) != len(ids):
        raise ConfigError(f"db_input['documents'] has {len(documents)} item(s) for {len(ids)} id(s)")
    if any(not i for i in ids):
        raise ConfigError("db_input['ids'] holds an empty id")
    if len(set(ids)) != len(ids):
        repeated = sorted({i for i in ids if ids.count(i) > 1})
        raise ConfigError(f"db_input['ids'] repeats {repeated}")
    metadatas = db_input.get("metadatas")
    if metadatas is not None:
        if not isinstance(metadatas, Sequence) or isinstance(metadatas, str) \
                or not all(m is None or isinstance(m, dict) for m in metadatas):
            raise ConfigError(f"db_input['metadatas'] must be a list of dict (or None), got {metadatas!r:.200}")
        if len(metadatas) != len(ids):
            raise ConfigError(f"db_input['metadatas'] has {len(metadatas)} item(s) for {len(ids)} id(s)")
        # Chroma stores an empty metadata as none at all; say so instead of sending {}.
        metadatas = [m if m else None for m in metadatas]
    vectors = db_input.get("embeddings")
    if vectors is not None:
        if not isinstance(vectors, Sequence) or len(vectors) != len(ids):
            raise ConfigError(f"db_input['embeddings'] must hold one vector per id ({len(ids)})")
        vectors = [check_vector(v, f"db_input['embeddings'][{k}]", ConfigError) for k, v in enumerate(vectors)]
    return ids, documents, metadatas, vectors


def check_vector(value: Any, where: str, error: type[ConfigError] | type[ProtocolError]) -> list[float]:
    """``value`` as a list of finite floats (numpy arrays included), else ``error`` naming ``where``."""
    try:
        vector = [float(x) for x in value]
    except (TypeError, ValueError):
        raise error(f"{where} must be a sequence of numbers, got {value!r:.200}") from None
    if not vector or not all(math.isfinite(x) for x in vector):
        raise error(f"{where} must be a non-empty vector of finite numbers")
    return vector


def check_where(where: Any) -> dict[str, Any]:
    """``db_input["where"]`` as Chroma accepts it (several plain keys joined by ``$and``)."""
    if not isinstance(where, dict) or not where:
        raise ConfigError(f"db_input['where'] must be a non-empty dict, got {where!r}")
    # Chroma accepts one key per filter level; several plain keys mean "all of them".
    if len(where) > 1 and not any(str(k).startswith("$") for k in where):
        return {"$and": [{k: v} for k, v in where.items()]}
    return where


def where_from_metadatas(metadatas: Any) -> dict[str, Any] | None:
    """Upstream's filter form: records matching any dict, where a dict matches when all its keys do."""
    if isinstance(metadatas, dict):
        metadatas = [metadatas]
    if not isinstance(metadatas, Sequence) or not all(isinstance(m, dict) for m in metadatas):
        raise ConfigError(f"db_input['metadatas'] must be a list of dict, got {metadatas!r:.200}")
    filters = [{k: {"$eq": v} for k, v in m.items()} for m in metadatas if m]
    if not filters:
        return None
    clauses = [f if len(f) == 1 else {"$and": [{k: v} for k, v in f.items()]} for f in filters]
    return clauses[0] if len(clauses) == 1 else {"$or": clauses}


def answer_column(answer: Any, key: str, *, nested: bool) -> list[Any] | None:
    """One column of a get/query answer (the first query's, when ``nested``), or None when absent."""
    if not isinstance(answer, dict):
        return None
    value = answer.get(key)
    if nested:
        value = value[0] if isinstance(value, list) and value else None
    return list(value) if isinstance(value, list) else None
