# Mirrors examples/complete_agent.py of automatika-robotics/embodied-agents, tag 0.6.0 (`agents` -> `agents_core`).
# The API calls are upstream's; the model servers are local stand-ins whose ports come from the environment.
import json
import os

import numpy as np

from agents_core.clients import ChromaClient, OllamaClient, RoboMLHTTPClient, RoboMLRESPClient
from agents_core.components import LLM, MLLM, MapEncoding, SemanticRouter, SpeechToText, TextToSpeech, Vision
from agents_core.config import LLMConfig, MapConfig, SemanticRouterConfig, TextToSpeechConfig, VisionConfig
from agents_core.models import OllamaModel, SpeechT5, VisionModel, Whisper
from agents_core.ros import FixedInput, Launcher, MapLayer, Route, Topic
from agents_core.vectordbs import ChromaDB

OLLAMA_PORT = int(os.environ.get("UPSTREAM_OLLAMA_PORT", "11434"))
ROBOML_PORT = int(os.environ.get("UPSTREAM_ROBOML_PORT", "8000"))
ROBOML_RESP_PORT = int(os.environ.get("UPSTREAM_ROBOML_RESP_PORT", "6379"))
CHROMA_PORT = int(os.environ.get("UPSTREAM_CHROMA_PORT", "8000"))
# Upstream's value. Upstream reads a float trigger as a period (every 15 s); here it is a rate (15 Hz), as the
# spec says, and the component says so at construction. A test sets UPSTREAM_TRIGGER to choose its own rate.
TRIGGER = float(os.environ.get("UPSTREAM_TRIGGER", "15.0"))

# -- the models, their servers and the vector database --
stt_model = Whisper(name="whisper")
stt_client = RoboMLHTTPClient(stt_model, port=ROBOML_PORT)
tts_model = SpeechT5(name="speecht5")
tts_client = RoboMLHTTPClient(tts_model, port=ROBOML_PORT)
detector_model = VisionModel(name="dino_4scale", checkpoint="dino-4scale_r50_8xb2-12e_coco")
detector_client = RoboMLRESPClient(detector_model, port=ROBOML_RESP_PORT)
vqa_model = OllamaModel(name="qwen_vl", checkpoint="qwen2.5vl:latest")
vqa_client = OllamaClient(vqa_model, port=OLLAMA_PORT)
chat_model = OllamaModel(name="llama", checkpoint="llama3.2:3b")
chat_client = OllamaClient(chat_model, port=OLLAMA_PORT)
store = ChromaDB()
store_client = ChromaClient(db=store, port=CHROMA_PORT)

# -- hearing: speech in, a question out --
speech = Topic(name="audio0", msg_type="Audio")
question = Topic(name="question", msg_type="String")

speech_to_text = SpeechToText(
    inputs=[speech],
    outputs=[question],
    model_client=stt_client,
    trigger=speech,
    component_name="speech_to_text",
)

# -- speaking: every answer is spoken on the robot --
answer = Topic(name="answer", msg_type="String")

text_to_speech = TextToSpeech(
    inputs=[answer],
    trigger=answer,
    model_client=tts_client,
    config=TextToSpeechConfig(play_on_device=True),
    component_name="text_to_speech",
)

# -- seeing: objects in the camera image --
camera = Topic(name="image_raw", msg_type="Image")
boxes = Topic(name="detections", msg_type="Detections")

vision = Vision(
    inputs=[camera],
    outputs=[boxes],
    trigger=camera,
    config=VisionConfig(threshold=0.5),
    model_client=detector_client,
    component_name="object_detection",
)

# -- questions about what the robot sees --
vqa_question = Topic(name="mllm_query", msg_type="String")

vqa = MLLM(
    inputs=[vqa_question, camera, boxes],
    outputs=[answer],
    model_client=vqa_client,
    trigger=vqa_question,
    component_name="visual_q_and_a",
)

vqa.set_component_prompt(
    template="""You are a robot looking at this image.
    The detector found: {{ detections }}.
    Answer this question about the image: {{ text0 }}"""
)

# -- which room is this, asked again and again --
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
    trigger=TRIGGER,
    component_name="introspector",
)


def room_word(output: str) -> str | None:
    # Only one of the three room words is published; any other answer publishes nothing.
    for room in ["office", "bedroom", "kitchen"]:
        if room in output.lower():
            return room
    return None


introspector.add_publisher_preprocessor(room_answer, room_word)

# -- the semantic map: what was seen and which room, where the robot was --
objects_layer = MapLayer(subscribes_to=boxes, temporal_change=True)
rooms_layer = MapLayer(subscribes_to=room_answer, resolution_multiple=3)

odometry = Topic(name="odom", msg_type="Odometry")
grid = Topic(name="map", msg_type="OccupancyGrid")

semantic_map = MapEncoding(
    layers=[objects_layer, rooms_layer],
    position=odometry,
    map_topic=grid,
    config=MapConfig(map_name="map"),
    db_client=store_client,
    trigger=TRIGGER,
    component_name="map_encoder",
)

# -- general questions --
chat_question = Topic(name="llm_query", msg_type="String")

chat = LLM(
    inputs=[chat_question],
    outputs=[answer],
    model_client=chat_client,
    trigger=[chat_question],
    component_name="general_q_and_a",
)

# -- "go to X": the place from the map, as a goal point --
goto_question = Topic(name="goto_query", msg_type="String")
goal_point = Topic(name="goal_point", msg_type="PoseStamped")

rag_config = LLMConfig(
    enable_rag=True,
    collection_name="map",
    distance_func="l2",
    n_results=1,
    add_metadata=True,
)

goto = LLM(
    inputs=[goto_question],
    outputs=[goal_point],
    model_client=chat_client,
    config=rag_config,
    db_client=store_client,
    trigger=goto_question,
    component_name="go_to_x",
)

goto.set_component_prompt(
    template="""Take the coordinates from the metadata and answer only with
    this json:\n {"position": coordinates}"""
)


def to_goal_point(output: str) -> np.ndarray | None:
    # The outermost {...} of the answer; its "position" is a comma-separated string of 2 or 3 numbers.
    try:
        found = json.loads(output[output.find("{") : output.rfind("}") + 1])
        xyz = np.fromstring(found["position"], sep=",", dtype=np.float64)
    except Exception:
        return None
    print("Coordinates Extracted:", xyz)
    if xyz.shape[0] == 2:  # a model often leaves out z on the floor
        xyz = np.append(xyz, 0)
    return xyz if xyz.shape[0] == 3 else None


goto.add_publisher_preprocessor(goal_point, to_goal_point)

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
    db_client=store_client,
    component_name="router",
)

launcher = Launcher()
launcher.add_pkg(
    components=[
        vqa,
        chat,
        goto,
        introspector,
        semantic_map,
        router,
        speech_to_text,
        text_to_speech,
        vision,
    ]
)
launcher.bringup()
