# Mirrors examples/prompt_engineering.py of automatika-robotics/embodied-agents, tag 0.7.4 (`agents` -> `agents_core`).
# The API calls are upstream's; the model servers are local stand-ins whose ports come from the environment.
import os

from agents_core.clients import OllamaClient, RoboMLRESPClient
from agents_core.components import MLLM, Vision
from agents_core.config import VisionConfig
from agents_core.models import OllamaModel, VisionModel
from agents_core.ros import Launcher, Topic

OLLAMA_PORT = int(os.environ.get("UPSTREAM_OLLAMA_PORT", "11434"))
ROBOML_RESP_PORT = int(os.environ.get("UPSTREAM_ROBOML_RESP_PORT", "6379"))

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

question = Topic(name="text0", msg_type="String")
answer = Topic(name="text1", msg_type="String")

vqa_model = OllamaModel(name="mllm_model", checkpoint="qwen2.5vl:latest")
vqa_client = OllamaClient(vqa_model, port=OLLAMA_PORT)

mllm = MLLM(
    inputs=[question, camera, boxes],
    outputs=[answer],
    model_client=vqa_client,
    trigger=question,
    component_name="mllm_component",
)

# The detections topic fills the {{ detections }} slot, the question the {{ text0 }} one.
mllm.set_component_prompt(
    template="""You are a robot looking at a picture.
    Items detected in it: {{ detections }}.
    Question about it: {{ text0 }}"""
)
launcher = Launcher()
launcher.enable_ui(inputs=[question], outputs=[answer, boxes])
launcher.add_pkg(components=[vision, mllm])
launcher.bringup()
