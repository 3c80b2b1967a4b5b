# Mirrors examples/semantic_map.py of automatika-robotics/embodied-agents, tag 0.6.0 (`agents` -> `agents_core`).
# The API calls are upstream's; the model servers are local stand-ins whose ports come from the environment.
import os

from agents_core.clients import ChromaClient, OllamaClient, RoboMLRESPClient
from agents_core.components import MLLM, MapEncoding, Vision
from agents_core.config import MapConfig, VisionConfig
from agents_core.models import OllamaModel, VisionModel
from agents_core.ros import FixedInput, Launcher, MapLayer, Topic
from agents_core.vectordbs import ChromaDB

OLLAMA_PORT = int(os.environ.get("UPSTREAM_OLLAMA_PORT", "11434"))
ROBOML_RESP_PORT = int(os.environ.get("UPSTREAM_ROBOML_RESP_PORT", "6379"))
CHROMA_PORT = int(os.environ.get("UPSTREAM_CHROMA_PORT", "8000"))
# Upstream's trigger=15.0 means "every 15 s" there (a period); here a float trigger is a rate in Hz, as the spec says.
# Set UPSTREAM_TRIGGER to run the recipe faster in a test.
EVERY_15_S = float(os.environ.get("UPSTREAM_TRIGGER", str(1 / 15)))

camera = Topic(name="image_raw", msg_type="Image")
boxes = Topic(name="detections", msg_type="Detections")

detector_model = VisionModel(name="object_detection", checkpoint="dino-4scale_r50_8xb2-12e_coco")
detector_client = RoboMLRESPClient(detector_model, port=ROBOML_RESP_PORT)

vision = Vision(
    inputs=[camera],
    outputs=[boxes],
    trigger=camera,
    config=VisionConfig(threshold=0.5),
    model_client=detector_client,
    component_name="detection_component",
)

vqa_model = OllamaModel(name="qwen_vl", checkpoint="qwen2.5vl:latest")
vqa_client = OllamaClient(vqa_model, port=OLLAMA_PORT)

room_question = FixedInput(
    name="introspection_query",
    msg_type="String",
    fixed="Which room is this: an office, a bedroom or a kitchen? Answer with one of these words.",
)
room_answer = Topic(name="introspection_answer", msg_type="String")

introspector = MLLM(
    inputs=[room_question, camera],
    outputs=[room_answer],
    model_client=vqa_client,
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

objects_layer = MapLayer(subscribes_to=boxes, temporal_change=True)
rooms_layer = MapLayer(subscribes_to=room_answer, resolution_multiple=3)

odometry = Topic(name="odom", msg_type="Odometry")
grid = Topic(name="map", msg_type="OccupancyGrid")

store = ChromaDB()
store_client = ChromaClient(db=store, port=CHROMA_PORT)

map_encoding = MapEncoding(
    layers=[objects_layer, rooms_layer],
    position=odometry,
    map_topic=grid,
    config=MapConfig(map_name="map"),
    db_client=store_client,
    trigger=EVERY_15_S,
    component_name="map_encoding",
)

launcher = Launcher()
launcher.add_pkg(components=[vision, introspector, map_encoding])
launcher.bringup()
