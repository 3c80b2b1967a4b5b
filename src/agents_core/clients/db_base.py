"""``DBClient``: the base of clients for vector databases (used by MapEncoding, SemanticRouter, RAG).

Implement the underscored methods; components call the public ones, which type every failure.

The ``db_input`` and result shapes components rely on (every call may name a
``"collection_name"``)::

    add / conditional_add: {"ids": [str], "documents": [str], "metadatas": [dict],   # metadatas optional
                            "distance_func": "l2" | "cosine" | "ip"}              # for a new collection
    query:                 {"query": str, "n_results": int, "where": dict}            # where optional
        -> {"ids": [...], "documents": [...], "metadatas": [...], "distances": [...]}  # nearest first
    metadata_query:        {"where": dict} -> {"ids": [...], "documents": [...], "metadatas": [...]}

:class:`~agents_core.clients.chroma.ChromaClient` documents the extra keys it accepts.
"""

from __future__ import annotations

from abc import abstractmethod
from typing import Any

from ..errors import ConfigError, InferenceError
from ..vectordbs import DB
from .client_base import BaseClient

__all__ = ["DBClient"]


class DBClient(BaseClient):
    """Connection to a vector database.

    :param db: the :class:`~agents_core.vectordbs.DB`, or its serialized dict.
    :param host: server host; :param port: server port;
    :param response_timeout: seconds a database call may take.
    """

    def __init__(
        self,
        db: DB | dict[str, Any],
        host: str | None = None,
        port: int | None = None,
        response_timeout: int | float = 30,
        init_on_activation: bool = True,
        logging_level: str = "info",
        **kwargs: Any,
    ) -> None:
        if kwargs:
            raise ConfigError(f"{type(self).__name__}: unexpected argument(s) {sorted(kwargs)}")
        super().__init__(host=host, port=port, init_on_activation=init_on_activation, logging_level=logging_level)
        if isinstance(db, DB):
            self.db_name = db.name
            self.db_type = type(db).__name__
            self.db_init_params: dict[str, Any] = db._get_init_params()
        elif isinstance(db, dict) and {"db_name", "db_type", "db_init_params"} <= set(db):
            self.db_name, self.db_type = str(db["db_name"]), str(db["db_type"])
            self.db_init_params = dict(db["db_init_params"])
        else:
            raise ConfigError(f"{type(self).__name__}: db must be a DB or its serialized dict")
        if isinstance(response_timeout, bool) or not isinstance(response_timeout, int | float) \
                or response_timeout <= 0:
            raise ConfigError(f"{type(self).__name__}: response_timeout must be > 0 s, got {response_timeout!r}")
        self.response_timeout = response_timeout

    @abstractmethod
    def _check_connection(self) -> None: ...

    @abstractmethod
    def _initialize(self) -> None: ...

    @abstractmethod
    def _add(self, db_input: dict[str, Any]) -> dict[str, Any] | None: ...

    @abstractmethod
    def _conditional_add(self, db_input: dict[str, Any]) -> dict[str, Any] | None: ...

    @abstractmethod
    def _query(self, db_input: dict[str, Any]) -> dict[str, Any] | None: ...

    @abstractmethod
    def _metadata_query(self, db_input: dict[str, Any]) -> dict[str, Any] | None: ...

    @abstractmethod
    def _deinitialize(self) -> None: ...

    def _checked(self, what: str, result: dict[str, Any] | None) -> dict[str, Any]:
        if result is None:
            raise InferenceError(f"{self._label()}: {what} on {self.db_name!r} returned nothing")
        return result

    def check_connection(self) -> None:
        """Verify the database is reachable."""
        self._guard("connection check", self._check_connection)

    def initialize(self) -> None:
        """Open the database / collections."""
        self._guard("initialize", self._initialize)

    def add(self, db_input: dict[str, Any]) -> dict[str, Any]:
        """Add (or upsert) documents."""
        return self._checked("add", self._guard("add", lambda: self._add(db_input)))

    def conditional_add(self, db_input: dict[str, Any]) -> dict[str, Any]:
        """Add documents whose ids are not there yet."""
        return self._checked("conditional add", self._guard("conditional add", lambda: self._conditional_add(db_input)))

    def query(self, db_input: dict[str, Any]) -> dict[str, Any]:
        """Nearest-neighbour query."""
        return self._checked("query", self._guard("query", lambda: self._query(db_input)))

    def metadata_query(self, db_input: dict[str, Any]) -> dict[str, Any]:
        """Query by metadata filter."""
        return self._checked("metadata query", self._guard("metadata query", lambda: self._metadata_query(db_input)))

    def deinitialize(self) -> None:
        """Close the database."""
        self._guard("deinitialize", self._deinitialize)

    def serialize(self) -> dict[str, Any]:
        spec = super().serialize()
        spec["db"] = {"db_name": self.db_name, "db_type": self.db_type, "db_init_params": self.db_init_params}
        spec["response_timeout"] = self.response_timeout
        return spec
