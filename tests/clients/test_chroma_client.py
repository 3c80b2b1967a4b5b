"""ChromaClient against a real Chroma server (``chroma run`` from the installed chromadb package).

The server is the thing under test; embeddings come from a small deterministic ModelClient
(hashed bag of words) so results do not depend on a model download.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import os
import re
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator, MutableMapping
from pathlib import Path
from typing import Any

import httpx
import pytest

from agents_core.clients import ChromaClient, ModelClient, client_from_spec
from agents_core.errors import (
    ClientConnectionError,
    ConfigError,
    HTTPStatusError,
    InferenceTimeoutError,
)
from agents_core.models import Model
from agents_core.testing.pairs import skip_unless_installed
from agents_core.vectordbs import ChromaDB

from ..conftest import free_tcp_port

_STARTUP_TIMEOUT_S = 60.0


class HashEmbeddingClient(ModelClient):
    """Hashed bag-of-words embeddings (L2-normalised): deterministic, no server, no model files."""

    def __init__(self, model: Any, dims: int = 64, api_key: str | None = None, **kwargs: Any) -> None:
        super().__init__(model=model, **kwargs)
        self.dims = dims
        self.api_key = api_key
        self.embedded: list[str] = []  # every text embedded, to see what was (not) embedded again

    def _check_connection(self) -> None:
        return None

    def _initialize(self) -> None:
        return None

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        return None

    def _deinitialize(self) -> None:
        return None

    def _embed(self, texts: list[str]) -> list[list[float]]:
        self.embedded.extend(texts)
        vectors = []
        for text in texts:
            vec = [0.0] * self.dims
            for word in re.findall(r"[a-z]+", text.lower()):
                vec[int(hashlib.md5(word.encode()).hexdigest(), 16) % self.dims] += 1.0
            norm = math.sqrt(sum(x * x for x in vec)) or 1.0
            vectors.append([x / norm for x in vec])
        return vectors

    def serialize(self) -> dict[str, Any]:
        spec = super().serialize()
        spec.update(dims=self.dims, api_key=self.api_key)
        return spec


class ChatOnlyClient(ModelClient):
    """A model client whose platform serves no embeddings."""

    def _check_connection(self) -> None:
        return None

    def _initialize(self) -> None:
        return None

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        return {"output": "hi"}

    def _deinitialize(self) -> None:
        return None


def _embedder(**kwargs: Any) -> HashEmbeddingClient:
    return HashEmbeddingClient(Model(name="hash", checkpoint="hash-bow-64"), **kwargs)


@pytest.fixture(scope="module")
def chroma_port(tmp_path_factory: pytest.TempPathFactory) -> Iterator[int]:
    """A real Chroma server on 127.0.0.1, storing under a temporary folder; stopped by its PID."""
    skip_unless_installed("", "chromadb",
                          reason="chromadb is not installed: it provides the `chroma` server these tests run against")
    chroma = Path(sys.executable).with_name("chroma")
    if not chroma.exists():
        pytest.skip(f"no `chroma` executable next to {sys.executable}")
    port = free_tcp_port()
    data = tmp_path_factory.mktemp("chroma")
    # Telemetry off: the tests must never reach beyond 127.0.0.1.
    env = {**os.environ, "ANONYMIZED_TELEMETRY": "False"}
    log_path = data / "server.log"
    with open(log_path, "wb") as log:
        # Its own session, so the server and any children it starts are stopped together.
        proc = subprocess.Popen([str(chroma), "run", "--host", "127.0.0.1", "--port", str(port),
                                 "--path", str(data / "db")],
                                stdout=log, stderr=subprocess.STDOUT, env=env, start_new_session=True)
    try:
        deadline = time.monotonic() + _STARTUP_TIMEOUT_S
        ready = False
        while not ready and time.monotonic() < deadline and proc.poll() is None:
            try:
                ready = httpx.get(f"http://127.0.0.1:{port}/api/v2/heartbeat", timeout=1.0).is_success
            except httpx.TransportError:
                time.sleep(0.1)
        if not ready:
            pytest.fail(f"chroma did not answer within {_STARTUP_TIMEOUT_S} s (exit code {proc.poll()}); "
                        f"log:\n{log_path.read_text(errors='replace')[-2000:]}")
        yield port
    finally:
        with contextlib.suppress(ProcessLookupError):  # it may have died on its own
            os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)


@pytest.fixture
def make_client(chroma_port: int) -> Iterator[Any]:
    """Builds clients on the test server and deinitializes every one of them afterwards."""
    made: list[ChromaClient] = []

    def make(collection: str, **db_fields: Any) -> ChromaClient:
        client_kwargs = {k: db_fields.pop(k) for k in ("embedding_client", "connection_retries") if k in db_fields}
        client_kwargs.setdefault("embedding_client", _embedder())
        client = ChromaClient(ChromaDB(name="test", collection_name=collection, **db_fields), port=chroma_port,
                              response_timeout=10, **client_kwargs)
        made.append(client)
        return client

    yield make
    for client in made:
        client.deinitialize()


PLACES = {
    "ids": ["sink", "door", "dock"],
    "documents": ["the kitchen sink is next to the fridge",
                  "front door opening onto the hallway",
                  "charging dock standing in the garage corner"],
    "metadatas": [{"room": "kitchen", "floor": 0}, {"room": "hallway", "floor": 0},
                  {"room": "garage", "floor": -1}],
}


def test_constructor_does_no_io_and_checks_its_arguments() -> None:
    port = free_tcp_port()  # nothing listens there
    client = ChromaClient(ChromaDB(name="map"), port=port, embedding_client=_embedder(api_key="s3cret"))
    assert client._http is None and client.base_url == f"http://127.0.0.1:{port}/api/v2"
    assert "s3cret" not in repr(client)
    with pytest.raises(ConfigError, match="distance_func"):
        ChromaDB(name="map", distance_func="dot")
    with pytest.raises(ConfigError, match="must be a ModelClient"):
        ChromaClient(ChromaDB(name="map"), embedding_client=client)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="ChatOnlyClient cannot compute embeddings"):
        ChromaClient(ChromaDB(name="map"), embedding_client=ChatOnlyClient(Model(name="chat", checkpoint="c")))
    with pytest.raises(ConfigError, match="connection_retries"):
        ChromaClient(ChromaDB(name="map"), connection_retries=-1)
    with pytest.raises(ConfigError, match="unknown field"):
        ChromaClient({"db_name": "m", "db_type": "ChromaDB", "db_init_params": {"colection_name": "x"}})


def test_serialize_round_trip_includes_the_embedding_client() -> None:
    client = ChromaClient(ChromaDB(name="map", collection_name="places", distance_func="cosine"), port=8123,
                          embedding_client=_embedder(dims=32, api_key="k"), connection_retries=0)
    spec = client.serialize()
    assert spec["embedding_client"]["client_type"] == "HashEmbeddingClient"
    rebuilt = client_from_spec(spec)
    assert isinstance(rebuilt, ChromaClient) and rebuilt == client
    assert isinstance(rebuilt.embedding_client, HashEmbeddingClient) and rebuilt.embedding_client.dims == 32
    assert rebuilt.settings.distance_func == "cosine" and rebuilt.settings.collection_name == "places"


def test_db_input_is_validated_before_any_request() -> None:
    # Nothing listens on this port: each error must come from validation, not the network.
    client = ChromaClient(ChromaDB(name="map"), port=free_tcp_port(), embedding_client=_embedder())
    with pytest.raises(ConfigError, match="lacks 'ids'"):
        client.add({"documents": ["a"]})
    with pytest.raises(ConfigError, match="lacks 'documents'"):
        client.add({"ids": ["a"]})
    with pytest.raises(ConfigError, match=r"'documents'\] has 1 item\(s\) for 2 id"):
        client.add({"ids": ["a", "b"], "documents": ["x"]})
    with pytest.raises(ConfigError, match=r"'metadatas'\] has 2 item\(s\) for 1 id"):
        client.conditional_add({"ids": ["a"], "documents": ["x"], "metadatas": [{}, {}]})
    with pytest.raises(ConfigError, match=r"repeats \['a'\]"):
        client.add({"ids": ["a", "a"], "documents": ["x", "y"]})
    with pytest.raises(ConfigError, match=r"unknown db_input key\(s\) \['metadata'\]"):
        client.add({"ids": ["a"], "documents": ["x"], "metadata": [{}]})
    with pytest.raises(ConfigError, match="'mode'"):
        client.add({"ids": ["a"], "documents": ["x"], "mode": "insert"})
    with pytest.raises(ConfigError, match="'query'"):
        client.query({"n_results": 2})
    with pytest.raises(ConfigError, match="n_results"):
        client.query({"query": "door", "n_results": 0})
    with pytest.raises(ConfigError, match="exactly one of"):
        client.metadata_query({})
    without_embedder = ChromaClient(ChromaDB(name="map", embeddings=None), port=free_tcp_port())
    with pytest.raises(ConfigError, match="needs embeddings"):
        without_embedder.add({"ids": ["a"], "documents": ["x"]})


def test_add_query_and_metadata_query(make_client: Any) -> None:
    client = make_client("places")
    client.check_connection()
    client.initialize()
    assert client.embedding_client.initialized
    assert client.add(PLACES) == {"collection_name": "places", "mode": "upsert", "ids": PLACES["ids"]}

    nearest = client.query({"query": "where is the fridge", "n_results": 3})
    assert nearest["ids"][0] == "sink" and nearest["documents"][0] == PLACES["documents"][0]
    assert nearest["metadatas"][0] == {"room": "kitchen", "floor": 0}
    assert nearest["distances"] == sorted(nearest["distances"]) and len(nearest["ids"]) == 3
    assert client.query({"query": "garage charging", "n_results": 1})["ids"] == ["dock"]
    # A metadata filter narrows the nearest-neighbour search.
    filtered = client.query({"query": "where is the fridge", "n_results": 3, "where": {"floor": {"$lt": 0}}})
    assert filtered["ids"] == ["dock"]

    hall = client.metadata_query({"where": {"room": "hallway"}})
    assert hall == {"collection_name": "places", "ids": ["door"], "documents": [PLACES["documents"][1]],
                    "metadatas": [{"room": "hallway", "floor": 0}]}
    # Several plain keys mean all of them (sent as $and, which Chroma requires).
    assert client.metadata_query({"where": {"floor": 0, "room": "kitchen"}})["ids"] == ["sink"]
    # Upstream's form: any of the dicts, each matching on all its keys.
    either = client.metadata_query({"metadatas": [{"room": "garage"}, {"room": "kitchen", "floor": 0}]})
    assert sorted(either["ids"]) == ["dock", "sink"]
    assert client.metadata_query({"where": {"room": "attic"}})["ids"] == []

    # Upsert replaces a record; mode "add" leaves an existing one alone.
    client.add({"ids": ["door"], "documents": ["back door to the garden"], "metadatas": [{"room": "garden"}]})
    client.add({"ids": ["door"], "documents": ["ignored"], "mode": "add"})
    assert client.metadata_query({"where": {"room": "garden"}})["documents"] == ["back door to the garden"]


def test_conditional_add_skips_existing_ids(make_client: Any) -> None:
    client = make_client("routes")
    client.initialize()
    embedder = client.embedding_client
    client.add({"ids": ["go_to_kitchen"], "documents": ["go to the kitchen"], "metadatas": [{"route": "nav"}]})
    embedder.embedded.clear()
    result = client.conditional_add({"ids": ["go_to_kitchen", "say_hello"],
                                     "documents": ["walk into the kitchen", "say hello to the guest"],
                                     "metadatas": [{"route": "navigation"}, {"route": "chat"}]})
    assert result == {"collection_name": "routes", "added": ["say_hello"], "skipped": ["go_to_kitchen"],
                      "updated_metadatas": ["go_to_kitchen"]}
    assert embedder.embedded == ["say hello to the guest"]  # the existing record was not embedded again
    kept = client.metadata_query({"where": {"route": "navigation"}})
    assert kept["ids"] == ["go_to_kitchen"] and kept["documents"] == ["go to the kitchen"]

    again = client.conditional_add({"ids": ["say_hello"], "documents": ["x"], "metadatas": [{"route": "other"}],
                                    "update_metadatas": False})
    assert again["added"] == [] and again["skipped"] == ["say_hello"] and again["updated_metadatas"] == []
    assert client.metadata_query({"where": {"route": "chat"}})["ids"] == ["say_hello"]
    # Chroma merges metadata: a new key joins the record's existing ones.
    client.conditional_add({"ids": ["say_hello"], "documents": ["x"], "metadatas": [{"polite": True}]})
    assert client.metadata_query({"where": {"polite": True}})["metadatas"] == [{"route": "chat", "polite": True}]


def test_tenant_database_and_distance_function_are_set_up(make_client: Any, chroma_port: int) -> None:
    client = make_client("cosine_places", tenant="robot_tenant", database="robot_db", distance_func="cosine")
    client.check_connection()
    client.initialize()
    client.add(PLACES)
    url = f"http://127.0.0.1:{chroma_port}/api/v2/tenants/robot_tenant/databases/robot_db/collections/cosine_places"
    info = httpx.get(url, timeout=5).json()
    assert info["configuration_json"]["hnsw"]["space"] == "cosine"
    result = client.query({"query": "the kitchen sink is next to the fridge", "n_results": 1})
    assert result["ids"] == ["sink"] and result["distances"][0] == pytest.approx(0.0, abs=1e-5)

    strict = make_client("x_places", database="absent_db", create_if_missing=False)
    with pytest.raises(HTTPStatusError, match=r"Database \[absent_db\] not found") as caught:
        strict.initialize()
    assert caught.value.status == 404


def test_precomputed_vectors_batches_and_reset(make_client: Any) -> None:
    client = make_client("vectors", embedding_client=None)
    client.initialize()
    client._database.max_batch = 2  # a small server batch limit, so five records take three requests
    ids = [f"p{k}" for k in range(5)]
    client.add({"ids": ids, "documents": ids, "embeddings": [[float(k), 1.0] for k in range(5)],
                "metadatas": [{"k": k} for k in range(5)]})
    assert client.query({"embedding": [3.1, 1.0], "n_results": 2})["ids"] == ["p3", "p4"]
    assert sorted(client.metadata_query({"where": {"k": {"$gte": 0}}})["ids"]) == ids
    assert len(client.metadata_query({"where": {"k": {"$gte": 0}}, "limit": 2})["ids"]) == 2

    # Another client resets the collection: this one's cached collection id goes stale and is renewed.
    other = make_client("vectors", embedding_client=None)
    other.add({"ids": ["q"], "documents": ["q"], "embeddings": [[0.0, 0.0]], "reset_collection": True})
    assert client.metadata_query({"where": {"k": {"$gte": 0}}})["ids"] == []
    assert client.query({"embedding": [3.0, 1.0], "n_results": 5})["ids"] == ["q"]


def test_typed_errors(make_client: Any, chroma_port: int) -> None:
    bad_name = make_client("a")  # Chroma wants 3 to 512 characters
    with pytest.raises(HTTPStatusError, match=r"Chroma answered 400: InvalidArgumentError: .*name") as caught:
        bad_name.initialize()
    assert caught.value.status == 400

    client = make_client("typed_errors")
    with pytest.raises(HTTPStatusError, match=r"Collection \[never_created\] does not exist") as missing:
        client.query({"query": "door", "collection_name": "never_created"})
    assert missing.value.status == 404
    client.add({"ids": ["x"], "documents": ["some words"]})
    with pytest.raises(HTTPStatusError, match="dimension of 64, got 2"):
        client.add({"ids": ["y"], "documents": ["y"], "embeddings": [[1.0, 0.0]]})

    refused = ChromaClient(ChromaDB(name="map"), port=free_tcp_port(), connection_retries=1)
    start = time.monotonic()
    with pytest.raises(ClientConnectionError, match="cannot reach the server"):
        refused.check_connection()
    assert time.monotonic() - start >= 0.5  # one bounded retry after a pause
    with pytest.raises(ClientConnectionError):
        refused.add({"ids": ["a"], "documents": ["a"], "embeddings": [[1.0]]})
    refused.deinitialize()

    # A server that accepts the connection but never answers.
    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen(1)
        slow = ChromaClient(ChromaDB(name="map"), port=silent.getsockname()[1], response_timeout=0.3,
                            connection_retries=0)
        with pytest.raises(InferenceTimeoutError):
            slow.check_connection()
