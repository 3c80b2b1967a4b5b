"""The tenant, database and collections of one :class:`~agents_core.vectordbs.ChromaDB` on a Chroma server.

:class:`ChromaDatabase` is what a :class:`~agents_core.clients.chroma.ChromaClient` knows about the
server's side: it makes sure the tenant and database exist (creating them when the ``ChromaDB``
allows it), learns the server's batch limit, gets or creates collections and caches their ids (a
stale id, of a collection deleted meanwhile, is looked up again once), and writes records in
batches of at most that limit. It sends its requests through the client's API call, so
authentication, timeouts and typed errors stay the client's.

Routes used, under ``/api/v2``: ``GET /pre-flight-checks`` (batch limit),
``GET|POST /tenants[/{tenant}]``, ``GET|POST /tenants/{tenant}/databases[/{database}]``, and under
``/tenants/{tenant}/databases/{database}``: ``POST /collections`` (get or create),
``GET|DELETE /collections/{name}``, ``POST /collections/{id}/get`` and the writes' routes.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any, Protocol, TypeVar
from urllib.parse import quote

from ...errors import HTTPStatusError, ProtocolError
from ...vectordbs import ChromaDB
from .db_input import answer_column

__all__ = ["ChromaDatabase"]

R = TypeVar("R")

# Used when the server does not say its batch limit (an older server without pre-flight checks).
_FALLBACK_BATCH = 1000


class ApiCall(Protocol):
    """One call of Chroma's API (the client's): its decoded JSON answer (None when empty), or a typed error."""

    def __call__(self, method: str, path: str, body: dict[str, Any] | None = None) -> Any: ...


class ChromaDatabase:
    """The server's side of one ``ChromaDB``: tenant and database set-up, collection ids, batched writes.

    :param api: the client's API call (paths relative to ``/api/v2``).
    :param settings: the ``ChromaDB`` (tenant, database, default collection and distance function).
    :param logger: the client's logger.
    :param label: the client's label for errors (``ChromaClient at host:port``).
    """

    def __init__(self, api: ApiCall, settings: ChromaDB, logger: logging.Logger, label: Callable[[], str]) -> None:
        self._api = api
        self.settings = settings
        self._logger = logger
        self._label = label
        #: collection name -> its id on the server.
        self.collection_ids: dict[str, str] = {}
        #: Whether the tenant and database were made sure of and the batch limit learnt.
        self.ready = False
        #: The server's largest batch (None until learnt).
        self.max_batch: int | None = None

    def forget(self) -> None:
        """Drop what was learnt from the server (the client closed; the next use asks again)."""
        self.collection_ids.clear()
        self.ready = False
        self.max_batch = None

    def path(self) -> str:
        """The database's route, ``/tenants/{tenant}/databases/{database}``."""
        return f"/tenants/{_segment(self.settings.tenant)}/databases/{_segment(self.settings.database)}"

    def prepare(self) -> None:
        """Make sure the tenant and database exist and learn the server's batch limit (once)."""
        if self.ready:
            return
        tenant = _segment(self.settings.tenant)
        self._ensure("tenant", f"/tenants/{tenant}", "/tenants", self.settings.tenant)
        self._ensure("database", self.path(), f"/tenants/{tenant}/databases", self.settings.database)
        size: Any = None
        try:
            checks = self._api("GET", "/pre-flight-checks")
            size = checks.get("max_batch_size") if isinstance(checks, dict) else None
        except HTTPStatusError as exc:
            if exc.status != 404:
                raise
        self.max_batch = size if isinstance(size, int) and not isinstance(size, bool) and size > 0 \
            else _FALLBACK_BATCH
        self.ready = True

    def _ensure(self, what: str, get_path: str, create_path: str, name: str) -> None:
        try:
            self._api("GET", get_path)
            return
        except HTTPStatusError as exc:
            if exc.status != 404 or not self.settings.create_if_missing:
                raise
        try:
            self._api("POST", create_path, {"name": name})
            self._logger.info("created Chroma %s %r", what, name)
        except HTTPStatusError as exc:
            # 409: someone created it between our look-up and our request, which is what we wanted.
            if exc.status != 409:
                raise

    def batch_size(self) -> int:
        """The server's largest batch (asked for on first use)."""
        self.prepare()
        return self.max_batch or _FALLBACK_BATCH

    def collection_id(self, name: str, *, create: bool, distance_func: str | None) -> str:
        """The collection's id, from the cache or the server (created first when ``create``)."""
        cached = self.collection_ids.get(name)
        if cached is not None:
            return cached
        self.prepare()
        collections = f"{self.path()}/collections"
        if create:
            space = distance_func or self.settings.distance_func
            info = self._api("POST", collections, {"name": name, "get_or_create": True,
                                                       "configuration": {"hnsw": {"space": space}}})
            actual = _space_of(info)
            if actual is not None and actual != space:
                # Chroma fixes the metric when a collection is created; it cannot be changed later.
                self._logger.warning("collection %r already exists with distance %r, not %r; keeping %r",
                                     name, actual, space, actual)
        else:
            info = self._api("GET", f"{collections}/{_segment(name)}")
        cid = info.get("id") if isinstance(info, dict) else None
        if not isinstance(cid, str) or not cid:
            raise ProtocolError(f"{self._label()}: collection {name!r}: answer without an id: {info!r}")
        self.collection_ids[name] = cid
        return cid

    def with_collection(self, name: str, create: bool, distance_func: str | None,
                        operation: Callable[[str], R]) -> R:
        """Run ``operation(collection path)``; once more with a fresh id if a cached one went stale."""
        was_cached = name in self.collection_ids
        cid = self.collection_id(name, create=create, distance_func=distance_func)
        try:
            return operation(f"{self.path()}/collections/{_segment(cid)}")
        except HTTPStatusError as exc:
            # Someone deleted (and maybe re-created) the collection since we cached its id.
            if exc.status != 404 or not was_cached:
                raise
            self.collection_ids.pop(name, None)
            cid = self.collection_id(name, create=create, distance_func=distance_func)
            return operation(f"{self.path()}/collections/{_segment(cid)}")

    def drop_collection(self, name: str) -> None:
        """Delete the collection ``name`` (nothing to do when it does not exist)."""
        self.prepare()
        self.collection_ids.pop(name, None)
        try:
            self._api("DELETE", f"{self.path()}/collections/{_segment(name)}")
            self._logger.info("deleted collection %r (reset_collection)", name)
        except HTTPStatusError as exc:
            if exc.status != 404:  # nothing to reset
                raise

    def existing_ids(self, path: str, ids: list[str]) -> set[str]:
        """Which of ``ids`` the collection at ``path`` holds."""
        found: set[str] = set()
        batch = self.batch_size()
        for start in range(0, len(ids), batch):
            answer = self._api("POST", f"{path}/get", {"ids": ids[start:start + batch], "include": []})
            found.update(answer_column(answer, "ids", nested=False) or [])
        return found

    def write(self, route: str, ids: list[str], documents: list[str], metadatas: list[Any] | None,
              vectors: list[list[float]]) -> None:
        """POST the records to ``route`` (a collection's add, upsert or update) in batches the server accepts."""
        batch = self.batch_size()
        for start in range(0, len(ids), batch):
            stop = start + batch
            body: dict[str, Any] = {"ids": ids[start:stop], "documents": documents[start:stop],
                                    "embeddings": vectors[start:stop]}
            if metadatas is not None:
                body["metadatas"] = metadatas[start:stop]
            self._api("POST", route, body)


def _segment(name: str) -> str:
    """``name`` as one URL path segment (a '/' in it must not change the route)."""
    return quote(name, safe="")


def _space_of(info: Any) -> str | None:
    config = info.get("configuration_json") if isinstance(info, dict) else None
    if not isinstance(config, dict):
        return None
    for index in ("hnsw", "spann"):
        section = config.get(index)
        if isinstance(section, dict) and isinstance(section.get("space"), str):
            return str(section["space"])
    return None


