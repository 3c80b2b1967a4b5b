"""Vector database descriptions, the ``DB`` counterpart of :class:`~agents_core.models.Model`."""

from __future__ import annotations

import os
import urllib.parse
from typing import Any

from attrs import define, field

from . import base_validators
from .config import BaseAttrs
from .errors import ConfigError
from .support.registry import Registry

__all__ = ["DB", "ChromaDB", "db_types"]

# Keyed by class name, as serialized clients name their database; a class defined again replaces the old one.
_db_types: Registry[type[DB]] = Registry("vector database class", hint="import the module that defines it first")


def db_types() -> dict[str, type[DB]]:
    """Every DB class defined so far, by class name."""
    return _db_types.snapshot()


def _non_empty_str(instance: Any, attribute: Any, value: Any) -> None:
    if not isinstance(value, str) or not value.strip():
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must be a non-empty str, got {value!r}")


def _bool(instance: Any, attribute: Any, value: Any) -> None:
    if not isinstance(value, bool):
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must be a bool, got {value!r}")


def _embeddings(instance: Any, attribute: Any, value: Any) -> None:
    if value == "sentence-transformers":
        raise ConfigError(f"{type(instance).__name__}.embeddings: sentence-transformers is not built in; give the "
                          "client an embedding_client (any model client with embed(), e.g. an OllamaClient or a "
                          "GenericHTTPClient on an embeddings server)")
    if value not in ("ollama", None):
        raise ConfigError(f"{type(instance).__name__}.embeddings must be 'ollama' or None, got {value!r}")


@define(kw_only=True)
class DB(BaseAttrs):
    """Base of vector database descriptions.

    :param name: an identifier chosen by the user.
    :param db_location: where the database keeps its data (a path or a server-side location).
    """

    name: str = field(validator=_non_empty_str)
    db_location: str = field(default="./data")

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        _db_types.register(cls.__name__, cls, replace=True)

    def _get_init_params(self) -> dict[str, Any]:
        """The parameters the database server needs to open this database."""
        return {"db_location": self.db_location}


_db_types.register("DB", DB, replace=True)


def _ollama_from_environment() -> tuple[str, int]:
    """``OLLAMA_HOST`` (``host``, ``host:port`` or ``http://host:port``) or Ollama's default address."""
    value = os.environ.get("OLLAMA_HOST", "").strip()
    if not value:
        return "127.0.0.1", 11434
    parsed = urllib.parse.urlsplit(value if "://" in value else f"http://{value}")
    try:
        port = parsed.port or 11434
    except ValueError as exc:
        raise ConfigError(f"OLLAMA_HOST={value!r} has no valid port: {exc}") from None
    return parsed.hostname or "127.0.0.1", port


@define(kw_only=True)
class ChromaDB(DB):
    """A collection in a `Chroma <https://www.trychroma.com>`_ server, used through
    :class:`~agents_core.clients.chroma.ChromaClient`.

    Chroma stores vectors but computes none over HTTP: the client's embedding client turns
    documents and queries into vectors. A client given none uses the embedding model named here,
    as upstream: ``ChromaDB()`` embeds with Ollama's ``bge-large:latest`` on 127.0.0.1:11434, or
    where the ``OLLAMA_HOST`` environment variable says (``host:port``, as Ollama's own CLI reads it).
    Names (tenant, database, collection) are checked by the server, whose rules may change
    between versions, so only emptiness is checked here.

    :param name: an identifier chosen by the user (default ``"chroma"``).
    :param db_location: where the server keeps its data (``chroma run --path``); informative
        only, since a remote server chooses its own path.
    :param tenant: the Chroma tenant holding the database.
    :param database: the Chroma database holding the collections.
    :param collection_name: the collection used when an operation names none.
    :param distance_func: ``"l2"`` (squared Euclidean), ``"cosine"`` (1 - cosine similarity) or
        ``"ip"`` (1 - inner product), the metric of collections this client creates. Chroma
        fixes it when a collection is created: an existing collection keeps its own.
    :param create_if_missing: create the tenant and the database when the server lacks them
        (collections are always created on first write).
    :param embeddings: the embedding backend of a client given no ``embedding_client``:
        ``"ollama"`` (upstream's default) or None (every ``db_input`` carries its vectors).
        Upstream's ``"sentence-transformers"`` runs in-process and is not built in: give an
        ``embedding_client`` instead.
    :param checkpoint: the Ollama embedding model.
    :param ollama_host: the Ollama server's host.
    :param ollama_port: its port.
    """

    name: str = field(default="chroma", validator=_non_empty_str)
    tenant: str = field(default="default_tenant", validator=_non_empty_str)
    database: str = field(default="default_database", validator=_non_empty_str)
    collection_name: str = field(default="agents_collection", validator=_non_empty_str)
    distance_func: str = field(default="l2", validator=base_validators.in_(["l2", "cosine", "ip"]))
    create_if_missing: bool = field(default=True, validator=_bool)
    embeddings: str | None = field(default="ollama", validator=_embeddings)
    checkpoint: str = field(default="bge-large:latest", validator=_non_empty_str)
    ollama_host: str = field(factory=lambda: _ollama_from_environment()[0], validator=_non_empty_str)
    ollama_port: int = field(factory=lambda: _ollama_from_environment()[1],
                             validator=base_validators.in_range(1, 65535))

    def _get_init_params(self) -> dict[str, Any]:
        return {
            "db_location": self.db_location,
            "tenant": self.tenant,
            "database": self.database,
            "collection_name": self.collection_name,
            "distance_func": self.distance_func,
            "create_if_missing": self.create_if_missing,
            "embeddings": self.embeddings,
            "checkpoint": self.checkpoint,
            "ollama_host": self.ollama_host,
            "ollama_port": self.ollama_port,
        }
