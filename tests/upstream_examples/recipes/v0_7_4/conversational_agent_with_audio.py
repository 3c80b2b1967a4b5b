# Mirrors examples/conversational_agent_with_audio.py of automatika-robotics/embodied-agents, tag 0.7.4
# (`agents` -> `agents_core`).
# The API calls are upstream's; the model servers are local stand-ins whose ports come from the environment.
import os

from agents_core.clients import OllamaClient, RoboMLWSClient
from agents_core.components import MLLM, SpeechToText, TextToSpeech
from agents_core.config import MLLMConfig, SpeechToTextConfig, TextToSpeechConfig
from agents_core.models import OllamaModel, TransformersTTS, Whisper
from agents_core.ros import Launcher, Topic

OLLAMA_PORT = int(os.environ.get("UPSTREAM_OLLAMA_PORT", "11434"))
ROBOML_PORT = int(os.environ.get("UPSTREAM_ROBOML_PORT", "8000"))

speech = Topic(name="audio0", msg_type="Audio")
transcript = Topic(name="text0", msg_type="String")

stt_model = Whisper(name="whisper")
stt_client = RoboMLWSClient(stt_model, port=ROBOML_PORT)

stt_config = SpeechToTextConfig(enable_vad=False)
speech_to_text = SpeechToText(
    inputs=[speech],
    outputs=[transcript],
    model_client=stt_client,
    trigger=speech,
    config=stt_config,
    component_name="speech_to_text",
)

camera = Topic(name="image_raw", msg_type="Image")
reply = Topic(name="text1", msg_type="String")

vqa_model = OllamaModel(name="qwen_vl", checkpoint="qwen2.5vl:latest")
vqa_client = OllamaClient(vqa_model, port=OLLAMA_PORT)
vqa_config = MLLMConfig(stream=True)

mllm = MLLM(
    inputs=[transcript, camera],
    outputs=[reply],
    model_client=vqa_client,
    trigger=transcript,
    config=vqa_config,
    component_name="vqa",
)

tts_config = TextToSpeechConfig(play_on_device=False, stream=True)

spoken = Topic(name="audio_out", msg_type="Audio")

tts_model = TransformersTTS(name="tts")
tts_client = RoboMLWSClient(tts_model, port=ROBOML_PORT)
text_to_speech = TextToSpeech(
    inputs=[reply],
    outputs=[spoken],
    trigger=reply,
    model_client=tts_client,
    config=tts_config,
    component_name="text_to_speech",
)

launcher = Launcher()
launcher.enable_ui(inputs=[speech, transcript], outputs=[camera, spoken])
launcher.add_pkg(components=[speech_to_text, mllm, text_to_speech])
launcher.bringup()
