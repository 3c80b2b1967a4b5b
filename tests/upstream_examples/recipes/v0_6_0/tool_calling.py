# Mirrors examples/tool_calling.py of automatika-robotics/embodied-agents, tag 0.6.0 (`agents` -> `agents_core`).
# The API calls are upstream's; the model servers are local stand-ins whose ports come from the environment.
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

goto.set_component_prompt(template="""Which position coordinates does the metadata give?""")


def get_coordinates(position: list[float]) -> np.ndarray:
    """The position as an array of floats."""
    return np.array(position, dtype=float)


coordinates_tool = {
    "type": "function",
    "function": {
        "name": "get_coordinates",
        "description": "Returns the position coordinates",
        "parameters": {
            "type": "object",
            "properties": {
                "position": {"type": "list[float]", "description": "x, y and z of the position"},
            },
        },
        "required": ["position"],
    },
}

goto.register_tool(
    tool=get_coordinates,
    tool_description=coordinates_tool,
    send_tool_response_to_model=False,
)

launcher = Launcher()
launcher.add_pkg(components=[goto])
launcher.bringup()
