# Mirrors examples/semantic_map.py of automatika-robotics/embodied-agents, tag 0.7.4 (`agents` -> `agents_core`).
# The API calls are upstream's; the model servers are local stand-ins whose ports come from the environment,
# and the memory's database path may too (UPSTREAM_MEMORY_DB; upstream writes /tmp/semantic_map.db).
import os

from agents_core.clients import OllamaClient, RoboMLRESPClient
from agents_core.components import VLM, Memory, Vision
from agents_core.config import MemoryConfig, VisionConfig
from agents_core.models import OllamaModel, VisionModel
from agents_core.ros import FixedInput, Launcher, MemLayer, Topic

OLLAMA_PORT = int(os.environ.get("UPSTREAM_OLLAMA_PORT", "11434"))
ROBOML_RESP_PORT = int(os.environ.get("UPSTREAM_ROBOML_RESP_PORT", "6379"))
MEMORY_DB = os.environ.get("UPSTREAM_MEMORY_DB", "/tmp/semantic_map.db")
# Upstream's trigger=15.0 means "every 15 s" there (a period); here a float trigger is a rate in Hz (see
# docs/porting.md). Set UPSTREAM_TRIGGER to run the recipe faster in a test.
EVERY_15_S = float(os.environ.get("UPSTREAM_TRIGGER", str(1 / 15)))

# Object detection on the camera.
camera = Topic(name="image_raw", msg_type="Image")
boxes = Topic(name="detections", msg_type="Detections")

detector_model = VisionModel(name="object_detection", checkpoint="PekingU/rtdetr_r50vd_coco_o365")
detector_client = RoboMLRESPClient(detector_model, port=ROBOML_RESP_PORT)

vision = Vision(
    inputs=[camera],
    outputs=[boxes],
    trigger=camera,
    config=VisionConfig(threshold=0.5),
    model_client=detector_client,
    component_name="detection_component",
)

# A vision-language model says which room the robot is in.
vlm_client = OllamaClient(OllamaModel(name="qwen_vl", checkpoint="qwen2.5vl:latest"), port=OLLAMA_PORT)

room_question = FixedInput(
    name="introspection_query",
    msg_type="String",
    fixed="Which room is this: an office, a bedroom or a kitchen? Answer with one of these words.",
)
room_answer = Topic(name="introspection_answer", msg_type="String")

introspector = VLM(
    inputs=[room_question, camera],
    outputs=[room_answer],
    model_client=vlm_client,
    trigger=EVERY_15_S,
    component_name="introspector",
)


def room_word(output: str) -> str | None:
    # Only one of the three room words is published; any other answer publishes nothing.
    for room in ["office", "bedroom", "kitchen"]:
        if room in output.lower():
            return room
    return None


introspector.add_publisher_preprocessor(room_answer, room_word)

# The memory: objects (every sighting, with its time) and the room (once per place).
objects_layer = MemLayer(subscribes_to=boxes, temporal_change=True)
rooms_layer = MemLayer(subscribes_to=room_answer)

# Embeddings from an embedding model served by Ollama (Memory downloads none).
embedder = OllamaClient(OllamaModel(name="embeddings", checkpoint="nomic-embed-text-v2-moe:latest"), port=OLLAMA_PORT)

odometry = Topic(name="odom", msg_type="Odometry")

memory = Memory(
    layers=[objects_layer, rooms_layer],
    position=odometry,
    model_client=vlm_client,  # summarises episodes when they are consolidated
    embedding_client=embedder,
    config=MemoryConfig(db_path=MEMORY_DB),
    trigger=EVERY_15_S,
    component_name="memory",
)

launcher = Launcher()
launcher.add_pkg(components=[vision, introspector, memory])
launcher.bringup()
