# Mirrors examples/memory_with_cortex.py of automatika-robotics/embodied-agents, tag 0.7.4
# (`agents` -> `agents_core`).
# The API calls are upstream's; the model servers are local stand-ins whose ports come from the environment
# (one Ollama stand-in serves the VLM, the planner and the embeddings; the detector is the built-in local
# classifier), and the memory file's place comes from UPSTREAM_MEMORY_DB (default: upstream's path).
import os

from agents_core.clients import OllamaClient
from agents_core.components import VLM, Cortex, Memory, TextToSpeech, Vision
from agents_core.config import CortexConfig, MemoryConfig, TextToSpeechConfig, VisionConfig
from agents_core.models import OllamaModel
from agents_core.ros import FixedInput, Launcher, MemLayer, Topic

OLLAMA_PORT = int(os.environ.get("UPSTREAM_OLLAMA_PORT", "11434"))
MEMORY_DB = os.environ.get("UPSTREAM_MEMORY_DB", "/tmp/memory_with_cortex.db")

# What the robot sees, and where it is.
camera = Topic(name="/image_raw", msg_type="Image")
odometry = Topic(name="/odom", msg_type="Odometry")

# Object detection on the built-in local classifier, once a second.
detections = Topic(name="detections", msg_type="Detections")
vision = Vision(
    inputs=[camera],
    outputs=[detections],
    config=VisionConfig(threshold=0.5, enable_local_classifier=True),
    trigger=1.0,
    component_name="vision",
)

# A one-sentence caption of the scene on a timer; Memory keeps the captions as a layer of their own.
caption_request = FixedInput(
    name="scene_query",
    msg_type="String",
    fixed="In one short sentence, say what kind of room this is, what stands out in it and who is there.",
)
scene_description = Topic(name="scene_description", msg_type="String")

vlm_client = OllamaClient(OllamaModel(name="gemma4", checkpoint="gemma4:latest"), port=OLLAMA_PORT)

captioner = VLM(
    inputs=[caption_request, camera],
    outputs=[scene_description],
    model_client=vlm_client,
    trigger=10.0,
    component_name="captioner",
)

# The memory: detections (only when they change), captions, and the battery as body state.
embedding_client = OllamaClient(OllamaModel(name="embeddings", checkpoint="nomic-embed-text-v2-moe:latest"),
                                port=OLLAMA_PORT)

detections_layer = MemLayer(subscribes_to=detections, temporal_change=True)
scene_layer = MemLayer(subscribes_to=scene_description)
battery_layer = MemLayer(
    subscribes_to=Topic(name="/battery_level", msg_type="Float32"),
    is_internal_state=True,
)

memory = Memory(
    layers=[detections_layer, scene_layer, battery_layer],
    position=odometry,
    model_client=vlm_client,
    embedding_client=embedding_client,
    config=MemoryConfig(
        db_path=MEMORY_DB,
        consolidation_window=300.0,
        archive_after_seconds=1800.0,
    ),
    trigger=10.0,
    component_name="memory",
)

# Cortex's answers are spoken on the robot.
cortex_replies = Topic(name="cortex_output", msg_type="StreamingString")
tts = TextToSpeech(
    inputs=[cortex_replies],
    config=TextToSpeechConfig(enable_local_model=True, play_on_device=True),
    trigger=cortex_replies,
    component_name="tts",
)

# The planner finds Memory's tools on its own; it shares the VLM's model.
cortex = Cortex(
    output=cortex_replies,
    model_client=vlm_client,
    config=CortexConfig(max_execution_steps=10),
    component_name="cortex",
)

launcher = Launcher()
launcher.enable_ui(inputs=[cortex.ui_main_action_input], outputs=[cortex_replies])
launcher.add_pkg(
    components=[vision, captioner, memory, tts, cortex],
    multiprocessing=True,
    package_name="automatika_embodied_agents",
)
launcher.on_process_fail()
launcher.bringup()
