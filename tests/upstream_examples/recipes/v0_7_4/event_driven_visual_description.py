# Mirrors examples/event_driven_visual_description.py of automatika-robotics/embodied-agents, tag 0.7.4
# (`agents` -> `agents_core`).
# The API calls are upstream's; the model servers are local stand-ins whose ports come from the environment.
import os

from agents_core.clients import OllamaClient
from agents_core.components import VLM, Vision
from agents_core.config import VisionConfig
from agents_core.models import OllamaModel
from agents_core.ros import Event, FixedInput, Launcher, Topic

OLLAMA_PORT = int(os.environ.get("UPSTREAM_OLLAMA_PORT", "11434"))

camera = Topic(name="/image_raw", msg_type="Image")
boxes = Topic(name="/detections", msg_type="Detections")
description = Topic(name="/description", msg_type="String")

# No model client: the detector runs on the built-in local classifier.
eye_config = VisionConfig(threshold=0.6, enable_local_classifier=True)
eye = Vision(
    inputs=[camera],
    outputs=[boxes],
    trigger=camera,
    config=eye_config,
    component_name="eye_detector",
)

# Fires when "person" appears among the labels (not while it stays there), at most once per 5 s.
someone_arrived = Event(
    boxes.msg.labels.contains_any(["person"]),
    on_change=True,
    keep_event_delay=5,
)

vlm_model = OllamaModel(name="qwen_vl", checkpoint="qwen2.5vl:7b")
vlm_client = OllamaClient(model=vlm_model, port=OLLAMA_PORT)

instruction = FixedInput(
    name="prompt",
    msg_type="String",
    fixed="Someone just came into view: say briefly what they look like.",
)

describer = VLM(
    inputs=[instruction, camera],
    outputs=[description],
    model_client=vlm_client,
    trigger=someone_arrived,
    component_name="visual_describer",
)

launcher = Launcher()
launcher.enable_ui(outputs=[boxes, description])
launcher.add_pkg(
    components=[eye, describer],
    multiprocessing=True,
    package_name="automatika_embodied_agents",
)
launcher.bringup()
