"""The DBClient contract with a real in-process vector store (no mocks): typed errors, serialization."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from attrs import define, field

from agents_core.clients import DBClient, client_from_spec
from agents_core.errors import ConfigError, InferenceError
from agents_core.vectordbs import DB


@define(kw_only=True)
class ArrayDB(DB):
    """A database description for the in-process store."""

    dims: int = field(default=3)

    def _get_init_params(self) -> dict[str, Any]:
        return {"db_location": self.db_location, "dims": self.dims}


class ArrayDBClient(DBClient):
    """Nearest-neighbour search over numpy arrays in memory."""

    def __init__(self, db: Any, **kwargs: Any) -> None:
        super().__init__(db=db, **kwargs)
        self.ids: list[str] = []
        self.vectors = np.zeros((0, int(self.db_init_params["dims"])))
        self.metadata: list[dict[str, Any]] = []

    def _check_connection(self) -> None:
        return None

    def _initialize(self) -> None:
        return None

    def _add(self, db_input: dict[str, Any]) -> dict[str, Any] | None:
        for i, vec, meta in zip(db_input["ids"], db_input["embeddings"], db_input["metadatas"], strict=True):
            self.ids.append(i)
            self.vectors = np.vstack([self.vectors, vec])
            self.metadata.append(meta)
        return {"added": len(db_input["ids"])}

    def _conditional_add(self, db_input: dict[str, Any]) -> dict[str, Any] | None:
        keep = [k for k, i in enumerate(db_input["ids"]) if i not in self.ids]
        return self._add({key: [db_input[key][k] for k in keep] for key in ("ids", "embeddings", "metadatas")})

    def _query(self, db_input: dict[str, Any]) -> dict[str, Any] | None:
        if not self.ids:
            return None
        d = np.linalg.norm(self.vectors - np.asarray(db_input["embedding"]), axis=1)
        order = np.argsort(d)[: db_input.get("n_results", 1)]
        return {"ids": [self.ids[k] for k in order], "distances": d[order].tolist()}

    def _metadata_query(self, db_input: dict[str, Any]) -> dict[str, Any] | None:
        where = db_input["where"]
        return {"ids": [i for i, m in zip(self.ids, self.metadata, strict=True)
                        if all(m.get(k) == v for k, v in where.items())]}

    def _deinitialize(self) -> None:
        return None


def test_db_client_contract() -> None:
    client = ArrayDBClient(ArrayDB(name="map", dims=2))
    with pytest.raises(InferenceError, match="query on 'map' returned nothing"):
        client.query({"embedding": [0, 0]})
    client.add({"ids": ["door"], "embeddings": [[1, 0]], "metadatas": [{"room": "hall"}]})
    assert client.conditional_add({"ids": ["door", "sink"], "embeddings": [[9, 9], [0, 1]],
                                   "metadatas": [{"room": "x"}, {"room": "kitchen"}]}) == {"added": 1}
    assert client.query({"embedding": [0.1, 0.9]})["ids"] == ["sink"]
    assert client.metadata_query({"where": {"room": "hall"}})["ids"] == ["door"]
    with pytest.raises(InferenceError, match="KeyError"):
        client.add({})
    rebuilt = client_from_spec(client.serialize())
    assert isinstance(rebuilt, ArrayDBClient) and rebuilt == client
    with pytest.raises(ConfigError, match="db must be a DB"):
        ArrayDBClient({"name": "x"})
