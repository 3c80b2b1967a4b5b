# Mirrors examples/tool_calling.py of automatika-robotics/embodied-agents, tag 0.7.4 (`agents` -> `agents_core`).
# The API calls are upstream's; the model servers are local stand-ins whose ports come from the environment,
# and the memory's database path may too (UPSTREAM_MEMORY_DB; upstream writes /tmp/tool_calling.db).
import os
import re

import numpy as np

from agents_core.clients import OllamaClient, RoboMLRESPClient
from agents_core.components import LLM, Memory, Vision
from agents_core.config import LLMConfig, MemoryConfig, VisionConfig
from agents_core.models import OllamaModel, VisionModel
from agents_core.ros import Launcher, MemLayer, Topic

OLLAMA_PORT = int(os.environ.get("UPSTREAM_OLLAMA_PORT", "11434"))
ROBOML_RESP_PORT = int(os.environ.get("UPSTREAM_ROBOML_RESP_PORT", "6379"))
MEMORY_DB = os.environ.get("UPSTREAM_MEMORY_DB", "/tmp/tool_calling.db")

# What the robot sees and where it is, remembered.
camera = Topic(name="image_raw", msg_type="Image")
boxes = Topic(name="detections", msg_type="Detections")
odometry = Topic(name="odom", msg_type="Odometry")

vision = Vision(
    inputs=[camera],
    outputs=[boxes],
    trigger=camera,
    config=VisionConfig(threshold=0.5),
    model_client=RoboMLRESPClient(
        VisionModel(name="rtdetr", checkpoint="PekingU/rtdetr_r50vd_coco_o365"), port=ROBOML_RESP_PORT
    ),
    component_name="vision",
)

embedder = OllamaClient(OllamaModel(name="embeddings", checkpoint="nomic-embed-text-v2-moe:latest"), port=OLLAMA_PORT)

memory = Memory(
    layers=[MemLayer(subscribes_to=boxes, temporal_change=True)],
    position=odometry,
    embedding_client=embedder,
    config=MemoryConfig(db_path=MEMORY_DB),
    trigger=10.0,
    component_name="memory",
)

# The LLM that sends the robot somewhere, through a tool of the recipe's own.
planner_client = OllamaClient(OllamaModel(name="qwen", checkpoint="qwen3.5:latest"), port=OLLAMA_PORT)

goto_in = Topic(name="goto_in", msg_type="String")
goal_point = Topic(name="goal_point", msg_type="PoseStamped")

goto = LLM(
    inputs=[goto_in],
    outputs=[goal_point],
    model_client=planner_client,
    trigger=goto_in,
    config=LLMConfig(),
    component_name="go_to_x",
)

goto.set_component_prompt(
    template=(
        "You are asked to take the robot to a place. Call the ``find_location_coordinates`` tool "
        "with the name of that place. The request: {{goto_in}}"
    )
)

LOCATION = re.compile(r"Location:\s*\(([^)]+)\)")


def find_location_coordinates(place: str) -> np.ndarray | None:
    """Where ``place`` was seen, as [x, y, z], asking the memory directly (None: unknown, nothing published).

    The array is the LLM's output: the framework turns it into the PoseStamped on ``goal_point``.
    """
    found = LOCATION.search(memory.locate(concept=place))
    if found is None:
        return None
    try:
        xyz = np.array([float(v) for v in found.group(1).split(",")], dtype=np.float64)
    except ValueError:
        return None
    if xyz.shape[0] == 2:
        xyz = np.append(xyz, 0.0)
    return xyz if xyz.shape[0] == 3 else None


find_location_description = {
    "type": "function",
    "function": {
        "name": "find_location_coordinates",
        "description": "Find the coordinates of a place the robot remembers and send the robot there.",
        "parameters": {
            "type": "object",
            "properties": {
                "place": {
                    "type": "string",
                    "description": "The name or a short description of the place (e.g. 'kitchen', 'the door').",
                },
            },
            "required": ["place"],
        },
    },
}

# The tool's value (the array) is published, not given back to the model.
goto.register_tool(
    tool=find_location_coordinates,
    tool_description=find_location_description,
    send_tool_response_to_model=False,
)

# One process: the tool calls the memory component directly.
launcher = Launcher()
launcher.add_pkg(components=[vision, memory, goto])
launcher.bringup()
