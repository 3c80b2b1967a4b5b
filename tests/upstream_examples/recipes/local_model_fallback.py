# Mirrors examples/local_model_fallback.py of automatika-robotics/embodied-agents, identical at tags 0.6.0 and 0.7.4
# (`agents` -> `agents_core`).
# The API calls are upstream's; the model servers are local stand-ins whose ports come from the environment.
import os

from agents_core.clients import RoboMLHTTPClient
from agents_core.components import LLM
from agents_core.models import TransformersLLM
from agents_core.ros import Action, Launcher, Topic

ROBOML_PORT = int(os.environ.get("UPSTREAM_ROBOML_PORT", "8000"))

# The remote model the component starts with.
remote_model = TransformersLLM(name="qwen_heavy", checkpoint="Qwen/Qwen2.5-1.5B-Instruct")
remote_client = RoboMLHTTPClient(model=remote_model, port=ROBOML_PORT)

question = Topic(name="user_query", msg_type="String")
answer = Topic(name="llm_response", msg_type="String")

brain = LLM(
    inputs=[question],
    outputs=[answer],
    model_client=remote_client,
    trigger=question,
    component_name="brain",
)

# When the remote model fails, answer with the built-in local model instead.
go_local = Action(method=brain.fallback_to_local)
brain.on_component_fail(action=go_local, max_retries=3)
brain.on_algorithm_fail(action=go_local, max_retries=3)

launcher = Launcher()
launcher.add_pkg(
    components=[brain],
    multiprocessing=True,
    package_name="automatika_embodied_agents",
)
launcher.bringup()
