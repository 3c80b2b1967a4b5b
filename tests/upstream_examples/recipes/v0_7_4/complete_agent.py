# Mirrors examples/complete_agent.py of automatika-robotics/embodied-agents, tag 0.7.4 (`agents` -> `agents_core`).
# The API calls are upstream's; the model servers are local stand-ins whose ports come from the environment,
# and the memory's database lives in UPSTREAM_MEMORY_DIR (upstream: /tmp).
import os
import re
import tempfile

import numpy as np

from agents_core.clients import ChromaClient, OllamaClient, RoboMLHTTPClient, RoboMLRESPClient
from agents_core.components import LLM, MLLM, Memory, SemanticRouter, SpeechToText, TextToSpeech, Vision
from agents_core.config import LLMConfig, MemoryConfig, SemanticRouterConfig, TextToSpeechConfig, VisionConfig
from agents_core.models import OllamaModel, TransformersTTS, VisionModel, Whisper
from agents_core.ros import FixedInput, Launcher, MemLayer, Route, Topic
from agents_core.vectordbs import ChromaDB

OLLAMA_PORT = int(os.environ.get("UPSTREAM_OLLAMA_PORT", "11434"))
ROBOML_PORT = int(os.environ.get("UPSTREAM_ROBOML_PORT", "8000"))
ROBOML_RESP_PORT = int(os.environ.get("UPSTREAM_ROBOML_RESP_PORT", "6379"))
CHROMA_PORT = int(os.environ.get("UPSTREAM_CHROMA_PORT", "8080"))
MEMORY_DIR = os.environ.get("UPSTREAM_MEMORY_DIR", tempfile.gettempdir())
# Upstream's value. Upstream reads a float trigger as a period (every 15 s); here it is a rate (15 Hz), as the
# spec says, and the component says so at construction. A test sets UPSTREAM_TRIGGER to choose its own rate.
TRIGGER = float(os.environ.get("UPSTREAM_TRIGGER", "15.0"))

# -- the models and their servers, shared by the components --
stt_client = RoboMLHTTPClient(Whisper(name="whisper"), port=ROBOML_PORT)
tts_client = RoboMLHTTPClient(TransformersTTS(name="tts"), port=ROBOML_PORT)
detector_client = RoboMLRESPClient(
    VisionModel(name="rtdetr", checkpoint="PekingU/rtdetr_r50vd_coco_o365"), port=ROBOML_RESP_PORT
)
vlm_client = OllamaClient(OllamaModel(name="qwen_vl", checkpoint="qwen2.5vl:latest"), port=OLLAMA_PORT)
chat_client = OllamaClient(OllamaModel(name="qwen", checkpoint="qwen3:0.6b"), port=OLLAMA_PORT)
embedder_client = OllamaClient(
    OllamaModel(name="embeddings", checkpoint="nomic-embed-text-v2-moe:latest"), port=OLLAMA_PORT
)
# The router still keeps its route samples in Chroma.
routes_store = ChromaClient(db=ChromaDB(), port=CHROMA_PORT)

# -- hearing and speaking --
speech = Topic(name="audio0", msg_type="Audio")
question = Topic(name="question", msg_type="String")
answer = Topic(name="answer", msg_type="String")

speech_to_text = SpeechToText(
    inputs=[speech],
    outputs=[question],
    model_client=stt_client,
    trigger=speech,
    component_name="speech_to_text",
)

text_to_speech = TextToSpeech(
    inputs=[answer],
    trigger=answer,
    model_client=tts_client,
    config=TextToSpeechConfig(play_on_device=True),
    component_name="text_to_speech",
)

# -- seeing: objects in the camera image --
camera = Topic(name="image_raw", msg_type="Image")
objects = Topic(name="detections", msg_type="Detections")

vision = Vision(
    inputs=[camera],
    outputs=[objects],
    trigger=camera,
    config=VisionConfig(threshold=0.5),
    model_client=detector_client,
    component_name="object_detection",
)

# -- questions about the image --
vqa_question = Topic(name="mllm_query", msg_type="String")

vqa = MLLM(
    inputs=[vqa_question, camera, objects],
    outputs=[answer],
    model_client=vlm_client,
    trigger=vqa_question,
    component_name="visual_q_and_a",
)
vqa.set_component_prompt(
    template=(
        "You are a robot. In this image the detector found: {{ detections }}. "
        "Answer this question about the image: {{ text0 }}"
    )
)

# -- which room this is, asked on a timer; the answer feeds the memory --
room_question = FixedInput(
    name="introspection_query",
    msg_type="String",
    fixed="Is this room an office, a bedroom or a kitchen? Answer with one of those three words only.",
)
room = Topic(name="introspection_answer", msg_type="String")

introspector = MLLM(
    inputs=[room_question, camera],
    outputs=[room],
    model_client=vlm_client,
    trigger=TRIGGER,
    component_name="introspector",
)


def room_word(output: str) -> str | None:
    # Publish one of the three room words, or nothing at all.
    for word in ["office", "bedroom", "kitchen"]:
        if word in output.lower():
            return word
    return None


introspector.add_publisher_preprocessor(room, room_word)

# -- the memory: what was seen and which room, where the robot was and when --
odometry = Topic(name="odom", msg_type="Odometry")

memory = Memory(
    layers=[
        MemLayer(subscribes_to=objects, temporal_change=True),
        MemLayer(subscribes_to=room),
    ],
    position=odometry,
    model_client=chat_client,
    embedding_client=embedder_client,
    config=MemoryConfig(db_path=os.path.join(MEMORY_DIR, "complete_agent.db")),
    trigger=TRIGGER,
    component_name="memory",
)

# -- anything else --
chat_question = Topic(name="llm_query", msg_type="String")

chat = LLM(
    inputs=[chat_question],
    outputs=[answer],
    model_client=chat_client,
    trigger=[chat_question],
    component_name="general_q_and_a",
)

# -- "go to X": the model looks the place up with the memory's locate tool --
goto_question = Topic(name="goto_query", msg_type="String")
goal_point = Topic(name="goal_point", msg_type="PoseStamped")

goto = LLM(
    inputs=[goto_question],
    outputs=[goal_point],
    model_client=chat_client,
    trigger=goto_question,
    config=LLMConfig(),
    component_name="go_to_x",
)
goto.set_component_prompt(
    template=(
        "You are asked to go somewhere. Find where that place is in memory with the tools you have: "
        "give its name to the locate tool as ``concept``. The request: {{goto_query}}"
    )
)
# The tool's own answer (not the model's) goes to the goal point's pre-processor below.
memory.register_tools_on(goto, tools=["locate"], send_tool_response_to_model=False)

LOCATION = re.compile(r"Location:\s*\(([^)]+)\)")


def goal_from_locate(output: str) -> np.ndarray | None:
    """The x, y(, z) that Memory.locate's text gives as the place's centre; None when it has none."""
    found = LOCATION.search(output)
    if found is None:
        return None
    try:
        xyz = np.fromstring(found.group(1), sep=",", dtype=np.float64)
    except ValueError:
        return None
    if xyz.shape[0] == 2:  # on the floor
        xyz = np.append(xyz, 0.0)
    return xyz if xyz.shape[0] == 3 else None


goto.add_publisher_preprocessor(goal_point, goal_from_locate)

# -- the router: each question to the component that can answer it --
goto_route = Route(
    routes_to=goto_question,
    samples=["Go to the door", "Go to the kitchen", "Get me a glass", "Fetch a ball", "Go to hallway"],
)
chat_route = Route(
    routes_to=chat_question,
    samples=[
        "What is the capital of France?",
        "Is there life on Mars?",
        "How many tablespoons in a cup?",
        "How are you today?",
        "Whats up?",
    ],
)
vqa_route = Route(
    routes_to=vqa_question,
    samples=[
        "Are we indoors or outdoors",
        "What do you see?",
        "Whats in front of you?",
        "Where are we",
        "Do you see any people?",
        "How many things are infront of you?",
        "Is this room occupied?",
    ],
)

router = SemanticRouter(
    inputs=[question],
    routes=[chat_route, goto_route, vqa_route],
    default_route=chat_route,
    config=SemanticRouterConfig(router_name="go-to-router", distance_func="l2"),
    db_client=routes_store,
    component_name="router",
)

# One process: the go-to-X model calls the memory's tool directly.
launcher = Launcher()
launcher.add_pkg(
    components=[vqa, chat, goto, introspector, memory, router, speech_to_text, text_to_speech, vision]
)
launcher.bringup()
