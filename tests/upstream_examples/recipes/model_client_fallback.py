# Mirrors examples/model_client_fallback.py of automatika-robotics/embodied-agents, identical at tags 0.6.0 and 0.7.4
# (`agents` -> `agents_core`).
# The API calls are upstream's; the model servers are local stand-ins whose ports come from the environment.
import os

from agents_core.clients import OllamaClient, RoboMLHTTPClient
from agents_core.components import LLM
from agents_core.config import LLMConfig
from agents_core.models import OllamaModel, TransformersLLM
from agents_core.ros import Action, Launcher, Topic

OLLAMA_PORT = int(os.environ.get("UPSTREAM_OLLAMA_PORT", "11434"))
ROBOML_PORT = int(os.environ.get("UPSTREAM_ROBOML_PORT", "8000"))

remote_model = TransformersLLM(name="qwen_heavy", checkpoint="Qwen/Qwen2.5-1.5B-Instruct")
remote_client = RoboMLHTTPClient(model=remote_model, port=ROBOML_PORT)

spare_model = OllamaModel(name="llama_local", checkpoint="llama3.2:3b")
spare_client = OllamaClient(model=spare_model, port=OLLAMA_PORT)

question = Topic(name="user_query", msg_type="String")
answer = Topic(name="llm_response", msg_type="String")

brain = LLM(
    inputs=[question],
    outputs=[answer],
    model_client=remote_client,
    trigger=question,
    component_name="brain",
    config=LLMConfig(stream=True),
)

# Clients the component may switch to, by key (set after construction, as upstream does).
brain.additional_model_clients = {"local_backup_client": spare_client}

use_spare = Action(method=brain.change_model_client, args=("local_backup_client",))
brain.on_component_fail(action=use_spare, max_retries=3)
brain.on_algorithm_fail(action=use_spare, max_retries=3)

launcher = Launcher()
launcher.add_pkg(
    components=[brain],
    multiprocessing=True,
    package_name="automatika_embodied_agents",
)
launcher.bringup()
