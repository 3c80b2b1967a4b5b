"""Components on real servers: a SemanticRouter and an LLM with RAG over a real Chroma server,
with the embeddings computed by a real llama.cpp server (SmolLM2, mean pooling) through
GenericHTTPClient. Nothing here is a test double except the LLM's chat answers.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from agents_core import Launcher, Topic
from agents_core.clients import ChromaClient, GenericHTTPClient
from agents_core.components import LLM, Route, SemanticRouter
from agents_core.config import LLMConfig, SemanticRouterConfig
from agents_core.models import GenericLLM
from agents_core.vectordbs import ChromaDB

from ..components.scripted_client import ScriptedChatClient
from ..conftest import wait_for
from .test_chroma_client import chroma_port  # noqa: F401  (a fixture, used by name)
from .test_generic_client import API_KEY, LlamaServer, llama_server  # noqa: F401

pytestmark = pytest.mark.local_models


def _embedder(server: LlamaServer) -> GenericHTTPClient:
    return GenericHTTPClient(GenericLLM(name="embed", checkpoint="smollm2-embed"), port=server.port, api_key=API_KEY)


@pytest.fixture
def chroma(chroma_port: int, llama_server: LlamaServer) -> Iterator[Any]:  # noqa: F811
    made: list[ChromaClient] = []

    def make(collection: str, distance_func: str = "cosine") -> ChromaClient:
        client = ChromaClient(ChromaDB(name="db", collection_name=collection, distance_func=distance_func),
                              port=chroma_port, embedding_client=_embedder(llama_server), response_timeout=30)
        made.append(client)
        return client

    yield make
    for client in made:
        client.deinitialize()


def test_semantic_router_vector_mode_on_real_chroma_and_real_embeddings(chroma: Any) -> None:
    requests, goto, chat, unsure = (Topic("requests", "String"), Topic("goto", "String"), Topic("chat", "String"),
                                    Topic("unsure", "String"))
    routes = [Route(routes_to=goto, samples=["go to the kitchen", "drive to the front door"]),
              Route(routes_to=chat, samples=["tell me a joke", "how are you today"])]
    db = chroma("router_routes")
    router = SemanticRouter(inputs=[requests], routes=routes, default_route=Route(routes_to=unsure, samples=["?"]),
                            db_client=db, config=SemanticRouterConfig(router_name="router_routes",
                                                                      distance_func="cosine", maximum_distance=0.5))
    launcher = Launcher("memory")
    launcher.add_pkg(components=[router])
    with launcher:
        got = {t.name: [] for t in (goto, chat, unsure)}  # type: dict[str, list[str]]
        for t in (goto, chat, unsure):
            launcher.transport.create_subscription(t, got[t.name].append)
        pub = launcher.transport.create_publisher(requests)
        # Near-copies of the samples: a 135M model's embeddings are coarse, but these are unambiguous.
        for text in ("go to the kitchen please", "tell me a joke please"):
            pub.publish(text)
        assert wait_for(lambda: sum(map(len, got.values())) == 2, timeout=30)
        stored = db.metadata_query({"collection_name": "router_routes", "where": {"route_name": "goto"}})
    assert got["goto"] == ["go to the kitchen please"] and got["chat"] == ["tell me a joke please"], got
    assert sorted(stored["ids"]) == ["goto:0", "goto:1"]


def test_llm_rag_reads_documents_from_real_chroma(chroma: Any) -> None:
    question, answer = Topic("question", "String"), Topic("answer", "String")
    db = chroma("house_notes")
    client = ScriptedChatClient(["noted"])
    llm = LLM(inputs=[question], outputs=[answer], model_client=client, db_client=db, trigger=question,
              config=LLMConfig(enable_rag=True, collection_name="house_notes", n_results=1))
    launcher = Launcher("memory")
    launcher.add_pkg(components=[llm])
    with launcher:
        llm.add_documents(ids=["charger", "keys"], documents=["The charging dock is in the garage.",
                                                             "The spare keys hang by the front door."])
        answers: list[str] = []
        launcher.transport.create_subscription(answer, answers.append)
        launcher.transport.create_publisher(question).publish("The charging dock is where?")
        assert wait_for(lambda: bool(answers), timeout=30)
    content = client.inputs[0]["query"][-1]["content"]
    assert "The charging dock is in the garage." in content, content
