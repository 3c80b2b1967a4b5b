# Mirrors examples/cortex_agent.py of automatika-robotics/embodied-agents, tag 0.7.4
# (`agents` -> `agents_core`).
# The API calls are upstream's; the model servers are local stand-ins whose ports come from the environment:
# the planner and the VLM on the Ollama stand-in, the detector on the RoboML RESP stand-in.
import os

from agents_core.clients import OllamaClient, RoboMLRESPClient
from agents_core.components import VLM, Cortex, TextToSpeech, Vision
from agents_core.config import CortexConfig, TextToSpeechConfig, VisionConfig
from agents_core.models import OllamaModel, VisionModel
from agents_core.ros import Action, Launcher, Topic

OLLAMA_PORT = int(os.environ.get("UPSTREAM_OLLAMA_PORT", "11434"))
ROBOML_RESP_PORT = int(os.environ.get("UPSTREAM_ROBOML_RESP_PORT", "6379"))

# The planner, a vision-language model and a detector, each behind its own client.
planner_client = OllamaClient(OllamaModel(name="qwen", checkpoint="qwen3.5:latest"), port=OLLAMA_PORT)
vlm_client = OllamaClient(OllamaModel(name="qwen_vl", checkpoint="qwen2.5vl:latest"), port=OLLAMA_PORT)
detection_client = RoboMLRESPClient(VisionModel(name="rtdetr", checkpoint="PekingU/rtdetr_r50vd_coco_o365"),
                                    port=ROBOML_RESP_PORT)

camera = Topic(name="/image_raw", msg_type="Image")
detections = Topic(name="detections", msg_type="Detections")
trackings = Topic(name="trackings", msg_type="Trackings")

# Detects at 2 Hz and follows a label once Cortex asks it to (its `track` action).
vision = Vision(
    inputs=[camera],
    outputs=[detections, trackings],
    model_client=detection_client,
    config=VisionConfig(threshold=0.5),
    trigger=0.5,
    component_name="vision",
)

# Answers questions about the camera image; its answers are also what the robot speaks.
question = Topic(name="vlm_query", msg_type="String")
spoken_text = Topic(name="text_in", msg_type="String")

vlm = VLM(
    inputs=[question, camera],
    outputs=[spoken_text],
    model_client=vlm_client,
    trigger=question,
    component_name="vlm",
)

# Speaks with the built-in voice on the robot's speaker.
tts = TextToSpeech(
    inputs=[spoken_text],
    outputs=[Topic(name="audio_out", msg_type="Audio")],
    config=TextToSpeechConfig(enable_local_model=True, play_on_device=True),
    trigger=spoken_text,
    component_name="tts",
)

led_on = False


def toggle_led():
    """Toggle an LED on the robot."""
    global led_on  # noqa: PLW0603  (upstream keeps the LED state in a module global)
    led_on = not led_on
    print(f"LED toggled {'ON' if led_on else 'OFF'}")


# Cortex's answers that need no action go here.
cortex_output = Topic(name="cortex_output", msg_type="StreamingString")

cortex = Cortex(
    actions=[Action(method=toggle_led, description="Toggle the robot's LED on or off.")],
    output=cortex_output,
    model_client=planner_client,
    config=CortexConfig(max_planning_steps=5, max_execution_steps=10),
    component_name="cortex",
)

launcher = Launcher()
launcher.enable_ui(inputs=[cortex.ui_main_action_input], outputs=[cortex_output])
launcher.add_pkg(
    components=[vision, vlm, tts, cortex],
    multiprocessing=True,
    package_name="automatika_embodied_agents",
)
launcher.bringup()
