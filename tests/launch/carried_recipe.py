"""A recipe run by tests/launch/test_carried_state.py, in upstream's ``model_client_fallback.py`` shape.

``python carried_recipe.py --port P --primary P1 --backup P2`` (from any directory): an LLM
``brain`` on an Ollama client (``--primary``) whose backup client (``--backup``) is set *after*
construction as ``additional_model_clients``, with a topic prompt, a publisher pre-processor and a
tool also added after construction, switching clients on failure; and a ``Ticker`` (a class from
the module next to this file) triggered by an Event. Both run in processes of their own on Zenoh.
"""

from __future__ import annotations

import argparse
import logging
import sys

from carried_components import Ticker, lookup, tag_answer  # a module next to this recipe

from agents_core.actions import Action
from agents_core.clients.ollama import OllamaClient
from agents_core.components.llm import LLM
from agents_core.events import Event
from agents_core.launch.launcher import Launcher
from agents_core.models import OllamaModel
from agents_core.topics import Topic


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--primary", type=int, required=True)
    parser.add_argument("--backup", type=int, required=True)
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, stream=sys.stderr)

    primary_client = OllamaClient(OllamaModel(name="primary", checkpoint="llama3.2:1b"), port=args.primary)
    backup_client = OllamaClient(OllamaModel(name="backup", checkpoint="llama3.2:1b"), port=args.backup)
    user_query = Topic(name="carry/query", msg_type="String")
    llm_response = Topic(name="carry/answer", msg_type="String")
    brain = LLM(inputs=[user_query], outputs=[llm_response], model_client=primary_client, trigger=user_query,
                component_name="brain")
    # Everything below happens after construction: each must reach brain's own process.
    brain.additional_model_clients = {"local_backup_client": backup_client}
    brain.set_topic_prompt(user_query, "Q: {{ carry_query }}")
    brain.add_publisher_preprocessor(llm_response, tag_answer)
    brain.register_tool(lookup, {"name": "lookup", "description": "Upper-case a key.",
                                 "parameters": {"type": "object", "properties": {"key": {"type": "string"}}}})
    switch_to_backup = Action(method=brain.change_model_client, args=("local_backup_client",))
    brain.on_component_fail(action=switch_to_backup, max_retries=3)
    brain.on_algorithm_fail(action=switch_to_backup, max_retries=3)

    go = Topic("carry/go", "String")
    ticker = Ticker(outputs=[Topic("carry/tick", "String")], trigger=Event("go_event", go.msg.data == "go"),
                    component_name="ticker")

    launcher = Launcher(transport="zenoh", transport_options={
        "mode": "peer", "listen": [f"tcp/127.0.0.1:{args.port}"], "connect": [], "multicast_scouting": False})
    launcher.add_pkg(components=[brain, ticker], multiprocessing=True, package_name="automatika_embodied_agents")
    launcher.bringup()


if __name__ == "__main__":
    main()
