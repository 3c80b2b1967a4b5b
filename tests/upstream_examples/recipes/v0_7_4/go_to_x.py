# Mirrors examples/go_to_x.py of automatika-robotics/embodied-agents, tag 0.7.4 (`agents` -> `agents_core`).
# The API calls are upstream's; the model servers are local stand-ins whose ports come from the environment,
# and the memory's database path may too (UPSTREAM_MEMORY_DB; upstream writes /tmp/go_to_x.db).
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
MEMORY_DB = os.environ.get("UPSTREAM_MEMORY_DB", "/tmp/go_to_x.db")

# What the robot sees and where it is.
camera = Topic(name="image_raw", msg_type="Image")
boxes = Topic(name="detections", msg_type="Detections")
odometry = Topic(name="odom", msg_type="Odometry")

detector = RoboMLRESPClient(
    VisionModel(name="rtdetr", checkpoint="PekingU/rtdetr_r50vd_coco_o365"), port=ROBOML_RESP_PORT
)
vision = Vision(
    inputs=[camera],
    outputs=[boxes],
    trigger=camera,
    config=VisionConfig(threshold=0.5),
    model_client=detector,
    component_name="vision",
)

# The memory embeds what it stores through an embedding model served by Ollama.
embedder = OllamaClient(OllamaModel(name="embeddings", checkpoint="nomic-embed-text-v2-moe:latest"), port=OLLAMA_PORT)

memory = Memory(
    layers=[MemLayer(subscribes_to=boxes, temporal_change=True)],
    position=odometry,
    embedding_client=embedder,
    config=MemoryConfig(db_path=MEMORY_DB),
    trigger=10.0,
    component_name="memory",
)

# An LLM that turns "go to X" into a goal point by asking the memory where X was seen.
planner_client = OllamaClient(OllamaModel(name="qwen", checkpoint="qwen3.5:latest"), port=OLLAMA_PORT)

goto_in = Topic(name="goto_in", msg_type="String")
goal_point = Topic(name="goal_point", msg_type="PoseStamped")

goto = LLM(
    inputs=[goto_in],
    outputs=[goal_point],
    model_client=planner_client,
    trigger=goto_in,
    config=LLMConfig(log_level="debug"),
    component_name="go_to_x",
)

goto.set_component_prompt(
    template=(
        "You are asked to take the robot to a place. Find where that place is with the tools you have: "
        "give its name to the locate tool as ``concept``. The request: {{goto_in}}"
    )
)

# Only Memory's locate tool; its text answer is published (through the pre-processor below), not sent back.
memory.register_tools_on(goto, tools=["locate"], send_tool_response_to_model=False)

# locate answers "Location: (x, y, z)" on its first line.
LOCATION = re.compile(r"Location:\s*\(([^)]+)\)")


def goal_from_locate(output: str) -> np.ndarray | None:
    """The x, y, z of locate's answer as an array (None, and nothing published, when it has none)."""
    found = LOCATION.search(output)
    if found is None:
        return None
    try:
        xyz = np.array([float(v) for v in found.group(1).split(",")], dtype=np.float64)
    except ValueError:
        return None
    if xyz.shape[0] == 2:  # on the floor
        xyz = np.append(xyz, 0.0)
    return xyz if xyz.shape[0] == 3 else None


goto.add_publisher_preprocessor(goal_point, goal_from_locate)

# One process: the LLM calls the memory's tool directly.
launcher = Launcher()
launcher.add_pkg(components=[vision, memory, goto])
launcher.bringup()
