"""``ChromaClient``: a :class:`~agents_core.clients.db_base.DBClient` speaking Chroma's v2 HTTP API.

The client checks the connection (``GET /api/v2/heartbeat``), embeds documents and query texts
with its ``embedding_client`` and runs the four operations; :mod:`.db_input` checks the
``db_input`` dicts (documented there) and reads the answers, :mod:`.database` keeps the tenant,
database and collections on the server. See :mod:`agents_core.clients.chroma` for authentication
and errors.
"""

from __future__ import annotations

import re
import time
from typing import Any, ClassVar

import httpx

from ...errors import ConfigError, HTTPStatusError, InferenceTimeoutError, ProtocolError
from ...vectordbs import DB, ChromaDB, db_types
from ..client_base import client_from_spec
from ..db_base import DBClient
from ..http_base import HTTPClientBase, bearer, check_api_key
from ..model_base import ModelClient
from .database import ChromaDatabase
from .db_input import (
    ADD_KEYS,
    CONDITIONAL_ADD_KEYS,
    METADATA_QUERY_KEYS,
    MODES,
    QUERY_KEYS,
    answer_column,
    check_distance,
    check_flag,
    check_keys,
    check_records,
    check_vector,
    check_where,
    where_from_metadatas,
)

__all__ = ["ChromaClient"]

_API_PREFIX = "/api/v2"
_RETRY_DELAY_S = 0.5
_MAX_RETRIES = 10

# An HTTP header name (RFC 9110 token characters that proxies accept in practice).
_HEADER_NAME = re.compile(r"^[A-Za-z0-9!#$%&'*+.^_`|~-]+$")


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
        serialized dict) computing embeddings. None: the ChromaDB's ``embeddings`` backend (an
        :class:`~agents_core.clients.ollama.OllamaClient` on its ``checkpoint``, used on first
        embedding, as upstream), or, with ``embeddings=None``, none: every ``db_input`` then
        carries its vectors.
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
        # Built from the ChromaDB's own fields (upstream's way): not serialized, rebuilt from them.
        self._embedder_from_db = embedder is None and self.settings.embeddings == "ollama"
        if self._embedder_from_db:
            embedder = self._ollama_embedder(logging_level)
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
        self._database = ChromaDatabase(self._api, self.settings, self.logger, self._label)

    def _ollama_embedder(self, logging_level: str) -> ModelClient:
        from ...models import OllamaModel  # noqa: PLC0415  (only a client without an embedding_client needs it)
        from ..ollama import OllamaClient  # noqa: PLC0415

        # Not initialized at configure (a pull would download the model): the first embedding uses it.
        return OllamaClient(OllamaModel(name=f"{self.db_name}_embeddings", checkpoint=self.settings.checkpoint),
                            host=self.settings.ollama_host, port=self.settings.ollama_port,
                            init_on_activation=False, logging_level=logging_level)

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
        if self.embedding_client is not None and not self._embedder_from_db:
            self.embedding_client.check_connection()

    def _initialize(self) -> None:
        self._database.prepare()
        self._database.collection_id(self.settings.collection_name, create=True, distance_func=None)
        emb = self.embedding_client
        if emb is not None and emb.init_on_activation and not emb.initialized:
            emb.initialize()
        self.logger.info("collection %r ready in %s/%s", self.settings.collection_name,
                         self.settings.tenant, self.settings.database)

    # -- embeddings -------------------------------------------------------------------------------

    def _embed(self, texts: list[str], what: str) -> list[list[float]]:
        if self.embedding_client is None:
            raise ConfigError(f"{type(self).__name__}: {what} needs embeddings: give an embedding_client, "
                              "ChromaDB(embeddings='ollama') or pass the vectors in db_input")
        vectors: list[list[float]] = []
        batch = self._database.batch_size()
        for start in range(0, len(texts), batch):
            chunk = self.embedding_client.embed(texts[start:start + batch])
            vectors.extend(check_vector(v, f"embedding_client.embed(...)[{start + k}]", ProtocolError)
                           for k, v in enumerate(chunk))
        return vectors

    # -- operations ----------------------------------------------------------------------------

    def _add(self, db_input: dict[str, Any]) -> dict[str, Any] | None:
        check_keys("add", db_input, ADD_KEYS)
        ids, documents, metadatas, vectors = check_records(db_input)
        mode = db_input.get("mode", "upsert")
        if mode not in MODES:
            raise ConfigError(f"db_input['mode'] must be one of {list(MODES)}, got {mode!r}")
        name = self._collection_name(db_input)
        distance = check_distance(db_input)
        if check_flag(db_input, "reset_collection", False):
            self._database.drop_collection(name)
        if vectors is None and ids:
            vectors = self._embed(documents, "add")

        def write(path: str) -> None:
            self._database.write(f"{path}/{mode}", ids, documents, metadatas, vectors or [])

        self._database.with_collection(name, True, distance, write)
        self.logger.debug("%s: %d record(s) into %r", mode, len(ids), name)
        return {"collection_name": name, "mode": mode, "ids": ids}

    def _conditional_add(self, db_input: dict[str, Any]) -> dict[str, Any] | None:
        check_keys("conditional_add", db_input, CONDITIONAL_ADD_KEYS)
        ids, documents, metadatas, vectors = check_records(db_input)
        update = check_flag(db_input, "update_metadatas", True)
        name = self._collection_name(db_input)
        # None where no metadata was given for a record: nothing to store or update for it.
        metas: list[Any] = metadatas if metadatas is not None else [None] * len(ids)

        def run(path: str) -> dict[str, Any]:
            existing = self._database.existing_ids(path, ids)
            new = [k for k, i in enumerate(ids) if i not in existing]
            old = [k for k, i in enumerate(ids) if i in existing]
            if new:
                new_docs = [documents[k] for k in new]
                new_vectors = [vectors[k] for k in new] if vectors is not None else self._embed(new_docs, "add")
                self._database.write(f"{path}/add", [ids[k] for k in new], new_docs,
                            [metadatas[k] for k in new] if metadatas is not None else None, new_vectors)
            # Only ids given a metadata dict have something to update.
            to_update = [k for k in old if metas[k] is not None] if update else []
            updated = [ids[k] for k in to_update]
            if to_update:
                batch = self._database.batch_size()
                for start in range(0, len(to_update), batch):
                    chunk = to_update[start:start + batch]
                    self._api("POST", f"{path}/update", {"ids": [ids[k] for k in chunk],
                                                             "metadatas": [metas[k] for k in chunk]})
            return {"collection_name": name, "added": [ids[k] for k in new], "skipped": [ids[k] for k in old],
                    "updated_metadatas": updated}

        result = self._database.with_collection(name, True, check_distance(db_input), run)
        self.logger.debug("conditional add into %r: %d added, %d skipped", name, len(result["added"]),
                          len(result["skipped"]))
        return result

    def _query(self, db_input: dict[str, Any]) -> dict[str, Any] | None:
        check_keys("query", db_input, QUERY_KEYS)
        name = self._collection_name(db_input)
        n_results = db_input.get("n_results", 10)
        if isinstance(n_results, bool) or not isinstance(n_results, int) or n_results < 1:
            raise ConfigError(f"db_input['n_results'] must be an int >= 1, got {n_results!r}")
        where = check_where(db_input["where"]) if db_input.get("where") is not None else None
        if db_input.get("embedding") is not None:
            vector = check_vector(db_input["embedding"], "db_input['embedding']", ConfigError)
        else:
            query = db_input.get("query")
            if not isinstance(query, str):
                raise ConfigError(f"db_input['query'] must be a str (or give 'embedding'), got {query!r}")
            vector = self._embed([query], "query")[0]
        body: dict[str, Any] = {"query_embeddings": [vector], "n_results": n_results,
                                "include": ["documents", "metadatas", "distances"]}
        if where is not None:
            body["where"] = where
        answer = self._database.with_collection(name, False, None,
                                                lambda path: self._api("POST", f"{path}/query", body))
        ids = answer_column(answer, "ids", nested=True)
        if ids is None:
            raise ProtocolError(f"{self._label()}: query answer without ids: {answer!r}")
        size = len(ids)
        return {"collection_name": name, "ids": ids,
                "documents": answer_column(answer, "documents", nested=True) or [None] * size,
                "metadatas": answer_column(answer, "metadatas", nested=True) or [None] * size,
                "distances": answer_column(answer, "distances", nested=True) or [None] * size}

    def _metadata_query(self, db_input: dict[str, Any]) -> dict[str, Any] | None:
        check_keys("metadata_query", db_input, METADATA_QUERY_KEYS)
        name = self._collection_name(db_input)
        if (db_input.get("where") is None) == (db_input.get("metadatas") is None):
            raise ConfigError("metadata_query needs exactly one of db_input['where'] and db_input['metadatas']")
        where = check_where(db_input["where"]) if db_input.get("where") is not None \
            else where_from_metadatas(db_input["metadatas"])
        if where is None:  # only empty metadata dicts: nothing to match (upstream behaviour)
            return {"collection_name": name, "ids": [], "documents": [], "metadatas": []}
        body: dict[str, Any] = {"where": where, "include": ["documents", "metadatas"]}
        limit = db_input.get("limit")
        if limit is not None:
            if isinstance(limit, bool) or not isinstance(limit, int) or limit < 1:
                raise ConfigError(f"db_input['limit'] must be an int >= 1, got {limit!r}")
            body["limit"] = limit
        answer = self._database.with_collection(name, False, None, lambda path: self._api("POST", f"{path}/get", body))
        ids = answer_column(answer, "ids", nested=False)
        if ids is None:
            raise ProtocolError(f"{self._label()}: get answer without ids: {answer!r}")
        return {"collection_name": name, "ids": ids,
                "documents": answer_column(answer, "documents", nested=False) or [None] * len(ids),
                "metadatas": answer_column(answer, "metadatas", nested=False) or [None] * len(ids)}

    def _deinitialize(self) -> None:
        try:
            # Also when it was used without initialize(): embedding opens its connection lazily.
            if self.embedding_client is not None:
                self.embedding_client.deinitialize()
        finally:
            self.close()
            self._database.forget()

    # -- helpers ------------------------------------------------------------------------------

    def _collection_name(self, db_input: dict[str, Any]) -> str:
        name = db_input.get("collection_name", self.settings.collection_name)
        if not isinstance(name, str) or not name.strip():
            raise ConfigError(f"db_input['collection_name'] must be a non-empty str, got {name!r}")
        return name

    # -- serialization ------------------------------------------------------------------------

    def serialize(self) -> dict[str, Any]:
        spec = super().serialize()
        given = None if self._embedder_from_db else self.embedding_client
        spec["embedding_client"] = given.serialize() if given is not None else None
        return spec

    def __repr__(self) -> str:
        # The embedding client's spec may hold its API key: show its repr, which hides secrets.
        return (f"{type(self).__name__}(db={self.db_name!r}, host={self.host!r}, port={self.port!r}, "
                f"collection={self.settings.collection_name!r}, api_key={'***' if self.api_key else None}, "
                f"embedding_client={self.embedding_client!r})")


