# Mirrors examples/go_to_x.py of automatika-robotics/embodied-agents, tag 0.6.0 (`agents` -> `agents_core`).
# The API calls are upstream's; the model servers are local stand-ins whose ports come from the environment.
import json
import os

import numpy as np

from agents_core.clients import ChromaClient, OllamaClient
from agents_core.components import LLM
from agents_core.config import LLMConfig
from agents_core.models import OllamaModel
from agents_core.ros import Launcher, Topic
from agents_core.vectordbs import ChromaDB

OLLAMA_PORT = int(os.environ.get("UPSTREAM_OLLAMA_PORT", "11434"))
CHROMA_PORT = int(os.environ.get("UPSTREAM_CHROMA_PORT", "8000"))

chat_model = OllamaModel(name="llama", checkpoint="llama3.2:3b")
chat_client = OllamaClient(chat_model, port=OLLAMA_PORT)

store = ChromaDB()
store_client = ChromaClient(db=store, port=CHROMA_PORT)

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
    # The outermost {...} of the answer; its "position" is a comma-separated string of 2 or 3 numbers.
    try:
        found = json.loads(output[output.find("{") : output.rfind("}") + 1])
        xyz = np.fromstring(found["position"], sep=",", dtype=np.float64)
    except Exception:
        return None
    if xyz.shape[0] == 2:  # a model often leaves out z on the floor
        xyz = np.append(xyz, 0)
    return xyz if xyz.shape[0] == 3 else None


goto.add_publisher_preprocessor(goal_point, to_goal_point)

launcher = Launcher()
launcher.add_pkg(components=[goto])
launcher.bringup()
