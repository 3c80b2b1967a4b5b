"""``ChromaClient``: a :class:`~agents_core.clients.db_base.DBClient` speaking Chroma's v2 HTTP API.

Only ``httpx`` is needed on the robot; the ``chromadb`` package is not imported. Chroma stores
and searches vectors but computes none over HTTP, so documents and query texts are embedded by
an ``embedding_client`` (any :class:`~agents_core.clients.model_base.ModelClient` whose
``embed(texts)`` works), unless the caller passes the vectors itself.

The ``db_input`` dicts. Every operation also takes ``"collection_name"`` (default: the
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

Routes used, under ``/api/v2``: ``GET /heartbeat``, ``GET /pre-flight-checks`` (batch limit),
``GET|POST /tenants[/{tenant}]``, ``GET|POST /tenants/{tenant}/databases[/{database}]``, and under
``/tenants/{tenant}/databases/{database}``: ``POST /collections`` (get or create),
``GET|DELETE /collections/{name}``, ``POST /collections/{id}/add|upsert|update|get|query``.
Writes larger than the server's ``max_batch_size`` are sent in several requests.

Authentication: a Chroma server started with token auth (or a proxy in front of it) wants a token
with every request. Give it as ``api_key``; ``auth_header`` says how it is sent:
``"Authorization"`` (default) sends ``Authorization: Bearer <token>``, ``"X-Chroma-Token"`` (or any
other header name a proxy expects) sends the bare token in that header, matching the server's
``chroma_auth_token_transport_header`` setting. The token is part of :meth:`ChromaClient.serialize`
and never appears in ``repr()``, logs, errors or status messages.

Errors: an HTTP error status raises :class:`~agents_core.errors.HTTPStatusError` carrying
Chroma's own message, an unreachable server :class:`~agents_core.errors.ClientConnectionError`,
a slow one :class:`~agents_core.errors.InferenceTimeoutError`, a malformed ``db_input``
:class:`~agents_core.errors.ConfigError` naming the field.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable, Sequence
from typing import Any, ClassVar, TypeVar
from urllib.parse import quote

import httpx

from ..errors import ConfigError, HTTPStatusError, InferenceTimeoutError, ProtocolError
from ..vectordbs import DB, ChromaDB, db_types
from .client_base import client_from_spec
from .db_base import DBClient
from .http_base import HTTPClientBase, bearer, check_api_key
from .model_base import ModelClient

__all__ = ["ChromaClient"]

R = TypeVar("R")

_API_PREFIX = "/api/v2"
_SPACES = ("l2", "cosine", "ip")
_MODES = ("upsert", "add")
# Used when the server does not say its batch limit (an older server without pre-flight checks).
_FALLBACK_BATCH = 1000
_RETRY_DELAY_S = 0.5
_MAX_RETRIES = 10

_ADD_KEYS = frozenset({"ids", "documents", "metadatas", "embeddings", "collection_name", "distance_func",
                       "mode", "reset_collection"})
_CONDITIONAL_ADD_KEYS = frozenset({"ids", "documents", "metadatas", "embeddings", "collection_name",
                                   "distance_func", "update_metadatas"})
# An HTTP header name (RFC 9110 token characters that proxies accept in practice).
_HEADER_NAME = re.compile(r"^[A-Za-z0-9!#$%&'*+.^_`|~-]+$")
_QUERY_KEYS = frozenset({"query", "embedding", "n_results", "where", "collection_name"})
_METADATA_QUERY_KEYS = frozenset({"where", "metadatas", "limit", "collection_name"})


class ChromaClient(HTTPClientBase, DBClient):
    """Client of a Chroma server (``chroma run``) through its v2 HTTP API.

    The constructor does no I/O. ``check_connection()`` asks for the server's heartbeat (retried,
    as it changes nothing) and checks the embedding client; ``initialize()`` makes sure the
    tenant and database exist (creating them when the :class:`~agents_core.vectordbs.ChromaDB`
    allows it), gets or creates the default collection with its distance function, and
    initializes the embedding client. Operations also work without ``initialize()``: what they
    need is prepared on first use. ``deinitialize()`` closes the HTTP connections.

    :param db: the :class:`~agents_core.vectordbs.ChromaDB`, or its serialized dict.
    :param host: the Chroma server's host.
    :param port: its port (``chroma run`` defaults to 8000).
    :param response_timeout: seconds one HTTP request may take, connect to last byte.
    :param embedding_client: the :class:`~agents_core.clients.model_base.ModelClient` (or its
        serialized dict) computing embeddings; may be None when every ``db_input`` carries its
        vectors.
    :param connection_retries: how many more times ``check_connection()`` asks for the
        heartbeat of a server that cannot be reached or answers 5xx (0 to 10).
    :param init_on_activation: call ``initialize()`` during configure.
    :param logging_level: ``"debug"``, ``"info"``, ...
    :param api_key: the token of a Chroma server with token auth (or of a proxy); None (default):
        no authentication header.
    :param auth_header: how ``api_key`` is sent: ``"Authorization"`` (default) as
        ``Authorization: Bearer <token>``; ``"X-Chroma-Token"`` or any other header name as the
        bare token in that header.
    :param use_https: talk HTTPS (a TLS proxy in front of Chroma, a hosted Chroma).
    """

    timeout_setting: ClassVar[str] = "response_timeout"
    status_template: ClassVar[str] = "Chroma answered {status}"
    base_path = _API_PREFIX
    spec_fields: ClassVar[tuple[str, ...]] = ("connection_retries", "api_key", "auth_header", "use_https")

    def __init__(
        self,
        db: ChromaDB | dict[str, Any],
        host: str = "127.0.0.1",
        port: int = 8000,
        response_timeout: int | float = 30,
        embedding_client: ModelClient | dict[str, Any] | None = None,
        connection_retries: int = 2,
        init_on_activation: bool = True,
        logging_level: str = "info",
        api_key: str | None = None,
        auth_header: str = "Authorization",
        use_https: bool = False,
        **kwargs: Any,
    ) -> None:
        super().__init__(db=db, host=host, port=port, response_timeout=response_timeout,
                         init_on_activation=init_on_activation, logging_level=logging_level, **kwargs)
        name = type(self).__name__
        if self.host is None or self.port is None:
            raise ConfigError(f"{name}: host and port are required")
        db_class = db_types().get(self.db_type)
        if (isinstance(db, DB) and not isinstance(db, ChromaDB)) or db_class is None \
                or not issubclass(db_class, ChromaDB):
            raise ConfigError(f"{name}: db must be a ChromaDB (or its dict), got a {self.db_type}")
        # Rebuilding the description checks a dict spec as strictly as a ChromaDB object.
        self.settings = ChromaDB.from_dict({"name": self.db_name, **self.db_init_params}, source=f"{name} db")
        self.db_init_params = self.settings._get_init_params()
        embedder = client_from_spec(embedding_client) if isinstance(embedding_client, dict) else embedding_client
        if embedder is not None:
            if not isinstance(embedder, ModelClient):
                raise ConfigError(f"{name}: embedding_client must be a ModelClient or its dict, "
                                  f"got {type(embedder).__name__}")
            if type(embedder)._embed is ModelClient._embed:
                raise ConfigError(f"{name}: embedding_client {type(embedder).__name__} cannot compute embeddings")
        self.embedding_client: ModelClient | None = embedder
        if isinstance(connection_retries, bool) or not isinstance(connection_retries, int) \
                or not 0 <= connection_retries <= _MAX_RETRIES:
            raise ConfigError(f"{name}: connection_retries must be an int in 0..{_MAX_RETRIES}, "
                              f"got {connection_retries!r}")
        self.connection_retries = connection_retries
        self.api_key = check_api_key(name, api_key)
        if not isinstance(auth_header, str) or not _HEADER_NAME.match(auth_header):
            raise ConfigError(f"{name}: auth_header must be an HTTP header name such as 'Authorization' or "
                              f"'X-Chroma-Token', got {auth_header!r}")
        self.auth_header = auth_header
        self.use_https = bool(use_https)
        self._collection_ids: dict[str, str] = {}
        self._database_ready = False
        self._max_batch: int | None = None

    # -- HTTP plumbing --------------------------------------------------------------------------

    def _headers(self) -> dict[str, str]:
        if self.auth_header.lower() == "authorization":
            return bearer(self.api_key)
        return {self.auth_header: self.api_key} if self.api_key else {}

    def _secrets(self) -> tuple[str, ...]:
        """The token, and the embedding client's secrets (its errors can pass through here)."""
        own = super()._secrets()
        return own + (self.embedding_client._secrets() if self.embedding_client is not None else ())

    def _api(self, method: str, path: str, body: dict[str, Any] | None = None, *, fresh: bool = False) -> Any:
        """One call of Chroma's API: its decoded JSON answer (None when empty), or a typed error.

        Chroma answers errors as ``{"error": "<kind>", "message": "<what went wrong>"}``, which
        the HTTPStatusError quotes as ``kind: message``.
        """
        what = f"{method} {_API_PREFIX}{path}"
        response = self._request(method, path, what, fresh=fresh, json=body)
        return self._json(response, what) if response.content else None

    def _database_path(self) -> str:
        return f"/tenants/{_segment(self.settings.tenant)}/databases/{_segment(self.settings.database)}"

    # -- connection and set-up --------------------------------------------------------------------

    def _check_connection(self) -> None:
        attempts = self.connection_retries + 1
        body: Any = None
        for attempt in range(attempts):
            try:
                # A short-lived connection: a connection check must leave nothing open behind it.
                body = self._api("GET", "/heartbeat", fresh=True)
                break
            except (httpx.TransportError, HTTPStatusError, InferenceTimeoutError) as exc:
                # Refused, timed out or 5xx may be a server still starting; 4xx will not change.
                retriable = not isinstance(exc, HTTPStatusError) or exc.status >= 500
                if not retriable or attempt == attempts - 1:
                    raise
                self.logger.debug("heartbeat attempt %d/%d failed (%s); retrying", attempt + 1, attempts, exc)
                time.sleep(_RETRY_DELAY_S)
        if not isinstance(body, dict) or "nanosecond heartbeat" not in body:
            raise ProtocolError(f"{self._label()}: GET {_API_PREFIX}/heartbeat answered {body!r}, "
                                "not a Chroma heartbeat")
        if self.embedding_client is not None:
            self.embedding_client.check_connection()

    def _initialize(self) -> None:
        self._prepare()
        self._collection_id(self.settings.collection_name, create=True, distance_func=None)
        emb = self.embedding_client
        if emb is not None and emb.init_on_activation and not emb.initialized:
            emb.initialize()
        self.logger.info("collection %r ready in %s/%s", self.settings.collection_name,
                         self.settings.tenant, self.settings.database)

    def _prepare(self) -> None:
        """Make sure the tenant and database exist and learn the server's batch limit (once)."""
        if self._database_ready:
            return
        tenant = _segment(self.settings.tenant)
        self._ensure("tenant", f"/tenants/{tenant}", "/tenants", self.settings.tenant)
        self._ensure("database", self._database_path(), f"/tenants/{tenant}/databases", self.settings.database)
        size: Any = None
        try:
            checks = self._api("GET", "/pre-flight-checks")
            size = checks.get("max_batch_size") if isinstance(checks, dict) else None
        except HTTPStatusError as exc:
            if exc.status != 404:
                raise
        self._max_batch = size if isinstance(size, int) and not isinstance(size, bool) and size > 0 \
            else _FALLBACK_BATCH
        self._database_ready = True

    def _ensure(self, what: str, get_path: str, create_path: str, name: str) -> None:
        try:
            self._api("GET", get_path)
            return
        except HTTPStatusError as exc:
            if exc.status != 404 or not self.settings.create_if_missing:
                raise
        try:
            self._api("POST", create_path, {"name": name})
            self.logger.info("created Chroma %s %r", what, name)
        except HTTPStatusError as exc:
            # 409: someone created it between our look-up and our request, which is what we wanted.
            if exc.status != 409:
                raise

    def _batch_size(self) -> int:
        self._prepare()
        return self._max_batch or _FALLBACK_BATCH

    def _collection_id(self, name: str, *, create: bool, distance_func: str | None) -> str:
        """The collection's id, from the cache or the server (created first when ``create``)."""
        cached = self._collection_ids.get(name)
        if cached is not None:
            return cached
        self._prepare()
        collections = f"{self._database_path()}/collections"
        if create:
            space = distance_func or self.settings.distance_func
            info = self._api("POST", collections, {"name": name, "get_or_create": True,
                                                       "configuration": {"hnsw": {"space": space}}})
            actual = _space_of(info)
            if actual is not None and actual != space:
                # Chroma fixes the metric when a collection is created; it cannot be changed later.
                self.logger.warning("collection %r already exists with distance %r, not %r; keeping %r",
                                    name, actual, space, actual)
        else:
            info = self._api("GET", f"{collections}/{_segment(name)}")
        cid = info.get("id") if isinstance(info, dict) else None
        if not isinstance(cid, str) or not cid:
            raise ProtocolError(f"{self._label()}: collection {name!r}: answer without an id: {info!r}")
        self._collection_ids[name] = cid
        return cid

    def _with_collection(self, name: str, create: bool, distance_func: str | None,
                         operation: Callable[[str], R]) -> R:
        """Run ``operation(collection path)``; once more with a fresh id if a cached one went stale."""
        was_cached = name in self._collection_ids
        cid = self._collection_id(name, create=create, distance_func=distance_func)
        try:
            return operation(f"{self._database_path()}/collections/{_segment(cid)}")
        except HTTPStatusError as exc:
            # Someone deleted (and maybe re-created) the collection since we cached its id.
            if exc.status != 404 or not was_cached:
                raise
            self._collection_ids.pop(name, None)
            cid = self._collection_id(name, create=create, distance_func=distance_func)
            return operation(f"{self._database_path()}/collections/{_segment(cid)}")

    def _drop_collection(self, name: str) -> None:
        self._prepare()
        self._collection_ids.pop(name, None)
        try:
            self._api("DELETE", f"{self._database_path()}/collections/{_segment(name)}")
            self.logger.info("deleted collection %r (reset_collection)", name)
        except HTTPStatusError as exc:
            if exc.status != 404:  # nothing to reset
                raise

    # -- embeddings -------------------------------------------------------------------------------

    def _embed(self, texts: list[str], what: str) -> list[list[float]]:
        if self.embedding_client is None:
            raise ConfigError(f"{type(self).__name__}: {what} needs embeddings: give an embedding_client "
                              "or pass the vectors in db_input")
        vectors: list[list[float]] = []
        batch = self._batch_size()
        for start in range(0, len(texts), batch):
            chunk = self.embedding_client.embed(texts[start:start + batch])
            vectors.extend(_vector(v, f"embedding_client.embed(...)[{start + k}]", ProtocolError)
                           for k, v in enumerate(chunk))
        return vectors

    # -- operations ----------------------------------------------------------------------------

    def _add(self, db_input: dict[str, Any]) -> dict[str, Any] | None:
        _check_keys("add", db_input, _ADD_KEYS)
        ids, documents, metadatas, vectors = _records(db_input)
        mode = db_input.get("mode", "upsert")
        if mode not in _MODES:
            raise ConfigError(f"db_input['mode'] must be one of {list(_MODES)}, got {mode!r}")
        name = self._collection_name(db_input)
        distance = _distance(db_input)
        if _flag(db_input, "reset_collection", False):
            self._drop_collection(name)
        if vectors is None and ids:
            vectors = self._embed(documents, "add")

        def write(path: str) -> None:
            self._write(f"{path}/{mode}", ids, documents, metadatas, vectors or [])

        self._with_collection(name, True, distance, write)
        self.logger.debug("%s: %d record(s) into %r", mode, len(ids), name)
        return {"collection_name": name, "mode": mode, "ids": ids}

    def _conditional_add(self, db_input: dict[str, Any]) -> dict[str, Any] | None:
        _check_keys("conditional_add", db_input, _CONDITIONAL_ADD_KEYS)
        ids, documents, metadatas, vectors = _records(db_input)
        update = _flag(db_input, "update_metadatas", True)
        name = self._collection_name(db_input)
        # None where no metadata was given for a record: nothing to store or update for it.
        metas: list[Any] = metadatas if metadatas is not None else [None] * len(ids)

        def run(path: str) -> dict[str, Any]:
            existing = self._existing(path, ids)
            new = [k for k, i in enumerate(ids) if i not in existing]
            old = [k for k, i in enumerate(ids) if i in existing]
            if new:
                new_docs = [documents[k] for k in new]
                new_vectors = [vectors[k] for k in new] if vectors is not None else self._embed(new_docs, "add")
                self._write(f"{path}/add", [ids[k] for k in new], new_docs,
                            [metadatas[k] for k in new] if metadatas is not None else None, new_vectors)
            # Only ids given a metadata dict have something to update.
            to_update = [k for k in old if metas[k] is not None] if update else []
            updated = [ids[k] for k in to_update]
            if to_update:
                batch = self._batch_size()
                for start in range(0, len(to_update), batch):
                    chunk = to_update[start:start + batch]
                    self._api("POST", f"{path}/update", {"ids": [ids[k] for k in chunk],
                                                             "metadatas": [metas[k] for k in chunk]})
            return {"collection_name": name, "added": [ids[k] for k in new], "skipped": [ids[k] for k in old],
                    "updated_metadatas": updated}

        result = self._with_collection(name, True, _distance(db_input), run)
        self.logger.debug("conditional add into %r: %d added, %d skipped", name, len(result["added"]),
                          len(result["skipped"]))
        return result

    def _query(self, db_input: dict[str, Any]) -> dict[str, Any] | None:
        _check_keys("query", db_input, _QUERY_KEYS)
        name = self._collection_name(db_input)
        n_results = db_input.get("n_results", 10)
        if isinstance(n_results, bool) or not isinstance(n_results, int) or n_results < 1:
            raise ConfigError(f"db_input['n_results'] must be an int >= 1, got {n_results!r}")
        where = _where(db_input["where"]) if db_input.get("where") is not None else None
        if db_input.get("embedding") is not None:
            vector = _vector(db_input["embedding"], "db_input['embedding']", ConfigError)
        else:
            query = db_input.get("query")
            if not isinstance(query, str):
                raise ConfigError(f"db_input['query'] must be a str (or give 'embedding'), got {query!r}")
            vector = self._embed([query], "query")[0]
        body: dict[str, Any] = {"query_embeddings": [vector], "n_results": n_results,
                                "include": ["documents", "metadatas", "distances"]}
        if where is not None:
            body["where"] = where
        answer = self._with_collection(name, False, None, lambda path: self._api("POST", f"{path}/query", body))
        ids = _column(answer, "ids", nested=True)
        if ids is None:
            raise ProtocolError(f"{self._label()}: query answer without ids: {answer!r}")
        size = len(ids)
        return {"collection_name": name, "ids": ids,
                "documents": _column(answer, "documents", nested=True) or [None] * size,
                "metadatas": _column(answer, "metadatas", nested=True) or [None] * size,
                "distances": _column(answer, "distances", nested=True) or [None] * size}

    def _metadata_query(self, db_input: dict[str, Any]) -> dict[str, Any] | None:
        _check_keys("metadata_query", db_input, _METADATA_QUERY_KEYS)
        name = self._collection_name(db_input)
        if (db_input.get("where") is None) == (db_input.get("metadatas") is None):
            raise ConfigError("metadata_query needs exactly one of db_input['where'] and db_input['metadatas']")
        where = _where(db_input["where"]) if db_input.get("where") is not None \
            else _where_from_metadatas(db_input["metadatas"])
        if where is None:  # only empty metadata dicts: nothing to match (upstream behaviour)
            return {"collection_name": name, "ids": [], "documents": [], "metadatas": []}
        body: dict[str, Any] = {"where": where, "include": ["documents", "metadatas"]}
        limit = db_input.get("limit")
        if limit is not None:
            if isinstance(limit, bool) or not isinstance(limit, int) or limit < 1:
                raise ConfigError(f"db_input['limit'] must be an int >= 1, got {limit!r}")
            body["limit"] = limit
        answer = self._with_collection(name, False, None, lambda path: self._api("POST", f"{path}/get", body))
        ids = _column(answer, "ids", nested=False)
        if ids is None:
            raise ProtocolError(f"{self._label()}: get answer without ids: {answer!r}")
        return {"collection_name": name, "ids": ids,
                "documents": _column(answer, "documents", nested=False) or [None] * len(ids),
                "metadatas": _column(answer, "metadatas", nested=False) or [None] * len(ids)}

    def _deinitialize(self) -> None:
        try:
            # Also when it was used without initialize(): embedding opens its connection lazily.
            if self.embedding_client is not None:
                self.embedding_client.deinitialize()
        finally:
            self.close()
            self._collection_ids.clear()
            self._database_ready = False
            self._max_batch = None

    # -- helpers ------------------------------------------------------------------------------

    def _collection_name(self, db_input: dict[str, Any]) -> str:
        name = db_input.get("collection_name", self.settings.collection_name)
        if not isinstance(name, str) or not name.strip():
            raise ConfigError(f"db_input['collection_name'] must be a non-empty str, got {name!r}")
        return name

    def _existing(self, path: str, ids: list[str]) -> set[str]:
        found: set[str] = set()
        batch = self._batch_size()
        for start in range(0, len(ids), batch):
            answer = self._api("POST", f"{path}/get", {"ids": ids[start:start + batch], "include": []})
            found.update(_column(answer, "ids", nested=False) or [])
        return found

    def _write(self, route: str, ids: list[str], documents: list[str], metadatas: list[Any] | None,
               vectors: list[list[float]]) -> None:
        batch = self._batch_size()
        for start in range(0, len(ids), batch):
            stop = start + batch
            body: dict[str, Any] = {"ids": ids[start:stop], "documents": documents[start:stop],
                                    "embeddings": vectors[start:stop]}
            if metadatas is not None:
                body["metadatas"] = metadatas[start:stop]
            self._api("POST", route, body)

    # -- serialization ------------------------------------------------------------------------

    def serialize(self) -> dict[str, Any]:
        spec = super().serialize()
        spec["embedding_client"] = self.embedding_client.serialize() if self.embedding_client is not None else None
        return spec

    def __repr__(self) -> str:
        # The embedding client's spec may hold its API key: show its repr, which hides secrets.
        return (f"{type(self).__name__}(db={self.db_name!r}, host={self.host!r}, port={self.port!r}, "
                f"collection={self.settings.collection_name!r}, api_key={'***' if self.api_key else None}, "
                f"embedding_client={self.embedding_client!r})")


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


def _check_keys(operation: str, db_input: Any, allowed: frozenset[str]) -> None:
    if not isinstance(db_input, dict):
        raise ConfigError(f"{operation}: db_input must be a dict, got {type(db_input).__name__}")
    unknown = sorted(set(db_input) - allowed)
    if unknown:
        raise ConfigError(f"{operation}: unknown db_input key(s) {unknown}; known: {sorted(allowed)}")


def _flag(db_input: dict[str, Any], key: str, default: bool) -> bool:
    value = db_input.get(key, default)
    if not isinstance(value, bool):
        raise ConfigError(f"db_input[{key!r}] must be a bool, got {value!r}")
    return value


def _distance(db_input: dict[str, Any]) -> str | None:
    value = db_input.get("distance_func")
    if value is not None and value not in _SPACES:
        raise ConfigError(f"db_input['distance_func'] must be one of {list(_SPACES)}, got {value!r}")
    return value


def _str_list(db_input: dict[str, Any], key: str) -> list[str]:
    if db_input.get(key) is None:
        raise ConfigError(f"db_input lacks {key!r} (a list of str)")
    value = db_input[key]
    if isinstance(value, str) or not isinstance(value, Sequence) or not all(isinstance(v, str) for v in value):
        raise ConfigError(f"db_input[{key!r}] must be a list of str, got {value!r:.200}")
    return list(value)


def _records(db_input: dict[str, Any]) -> tuple[list[str], list[str], list[Any] | None, list[list[float]] | None]:
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
        vectors = [_vector(v, f"db_input['embeddings'][{k}]", ConfigError) for k, v in enumerate(vectors)]
    return ids, documents, metadatas, vectors


def _vector(value: Any, where: str, error: type[ConfigError] | type[ProtocolError]) -> list[float]:
    """``value`` as a list of finite floats (numpy arrays included), else ``error`` naming ``where``."""
    try:
        vector = [float(x) for x in value]
    except (TypeError, ValueError):
        raise error(f"{where} must be a sequence of numbers, got {value!r:.200}") from None
    if not vector or not all(math.isfinite(x) for x in vector):
        raise error(f"{where} must be a non-empty vector of finite numbers")
    return vector


def _where(where: Any) -> dict[str, Any]:
    if not isinstance(where, dict) or not where:
        raise ConfigError(f"db_input['where'] must be a non-empty dict, got {where!r}")
    # Chroma accepts one key per filter level; several plain keys mean "all of them".
    if len(where) > 1 and not any(str(k).startswith("$") for k in where):
        return {"$and": [{k: v} for k, v in where.items()]}
    return where


def _where_from_metadatas(metadatas: Any) -> dict[str, Any] | None:
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


def _column(answer: Any, key: str, *, nested: bool) -> list[Any] | None:
    """One column of a get/query answer (the first query's, when ``nested``), or None when absent."""
    if not isinstance(answer, dict):
        return None
    value = answer.get(key)
    if nested:
        value = value[0] if isinstance(value, list) and value else None
    return list(value) if isinstance(value, list) else None
