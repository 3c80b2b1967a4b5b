# Mirrors examples/semantic_router.py of automatika-robotics/embodied-agents, tag 0.7.4 (`agents` -> `agents_core`).
# The API calls are upstream's; the model servers are local stand-ins whose ports come from the environment.
import json
import os

import numpy as np

from agents_core.clients import ChromaClient, OllamaClient
from agents_core.components import LLM, SemanticRouter
from agents_core.config import LLMConfig, SemanticRouterConfig
from agents_core.models import OllamaModel
from agents_core.ros import Launcher, Route, Topic
from agents_core.vectordbs import ChromaDB

OLLAMA_PORT = int(os.environ.get("UPSTREAM_OLLAMA_PORT", "11434"))
CHROMA_PORT = int(os.environ.get("UPSTREAM_CHROMA_PORT", "8000"))

chat_model = OllamaModel(name="qwen", checkpoint="qwen3:0.6b")
chat_client = OllamaClient(chat_model, port=OLLAMA_PORT)

store = ChromaDB()
store_client = ChromaClient(db=store, port=CHROMA_PORT)

chat_in = Topic(name="text_in_llm", msg_type="String")
chat_out = Topic(name="text_out_llm", msg_type="String")

chat = LLM(
    inputs=[chat_in],
    outputs=[chat_out],
    model_client=chat_client,
    trigger=chat_in,
    component_name="generic_llm",
)

goto_in = Topic(name="goto_in", msg_type="String")
goal_point = Topic(name="goal_point", msg_type="PoseStamped")

rag_config = LLMConfig(
    enable_rag=True,
    collection_name="map",
    distance_func="l2",
    n_results=1,
    add_metadata=True,
)

goto = LLM(
    inputs=[goto_in],
    outputs=[goal_point],
    model_client=chat_client,
    db_client=store_client,
    trigger=goto_in,
    config=rag_config,
    component_name="go_to_x",
)

goto.set_component_prompt(
    template="""Read the coordinates from the metadata and answer only with
    this json: {"position": coordinates}"""
)


def to_goal_point(output: str) -> np.ndarray | None:
    # The first {...} in the answer, read as JSON; anything else publishes nothing.
    start, end = output.find("{"), output.find("}")
    try:
        return np.array(json.loads(output[start : end + 1])["position"])
    except Exception:
        return None


goto.add_publisher_preprocessor(goal_point, to_goal_point)

query = Topic(name="question", msg_type="String")

goto_route = Route(
    routes_to=goto_in,
    samples=["Go to the door", "Go to the kitchen", "Get me a glass", "Fetch a ball", "Go to hallway"],
)

chat_route = Route(
    routes_to=chat_in,
    samples=[
        "What is the capital of France?",
        "Is there life on Mars?",
        "How many tablespoons in a cup?",
        "How are you today?",
        "Whats up?",
    ],
)

router_config = SemanticRouterConfig(router_name="go-to-router", distance_func="l2")

router = SemanticRouter(
    inputs=[query],
    routes=[chat_route, goto_route],
    default_route=chat_route,
    config=router_config,
    db_client=store_client,
    component_name="router",
)

launcher = Launcher()
launcher.add_pkg(components=[chat, goto, router])
launcher.bringup()
