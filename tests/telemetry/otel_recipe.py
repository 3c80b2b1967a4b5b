"""The telemetry tests' recipe: ``python -m tests.telemetry.otel_recipe --transport zenoh --listen EP --ollama-port P``.

Two components, a process each (``multiprocessing=True``): ``asker`` (the framework's LLM
component, its OllamaClient on the scripted Ollama server of the test) answers ``otel/question``
on ``otel/mid``; ``checker`` (a component of this file) asks the same model about that answer
through its own client and publishes on ``otel/answer`` the reply, its pid and whether
OpenTelemetry is loaded in its process (``otel=True`` / ``otel=False``).
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from agents_core import Component, Launcher, Topic
from agents_core.clients import OllamaClient
from agents_core.components import LLM
from agents_core.models import OllamaModel
from agents_core.supported_types import String
from tests.components.recipe_main import serve, transport_options

QUESTION = Topic(name="otel/question", msg_type="String")
MID = Topic(name="otel/mid", msg_type="String")
ANSWER = Topic(name="otel/answer", msg_type="String")
MODEL = "qwen2.5:0.5b"


class Checker(Component):
    """Asks the model about each text and publishes the reply with its pid and ``otel=<loaded>``."""

    def __init__(self, client: OllamaClient, component_name: str = "checker", **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Required": [String]}
        super().__init__(inputs=[MID], outputs=[ANSWER], trigger=MID, component_name=component_name, **kwargs)
        self.client = client

    def custom_on_configure(self) -> None:
        self.client.check_connection()

    def _execution_step(self, **kwargs: Any) -> None:
        text = self.trig_callbacks[MID.name].get_output()
        reply = self.client.inference({"query": [{"role": "user", "content": f"check: {text}"}]})
        loaded = any(name.startswith("opentelemetry") for name in sys.modules)
        self.publishers_dict[ANSWER.name].publish(f"{reply['output']} [pid={os.getpid()} otel={loaded}]")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--transport", required=True, choices=["zenoh"])
    parser.add_argument("--listen", required=True)
    parser.add_argument("--ollama-port", type=int, required=True)
    args = parser.parse_args(argv)
    model = OllamaModel(name="tiny", checkpoint=MODEL)
    asker = LLM(inputs=[QUESTION], outputs=[MID], model_client=OllamaClient(model, port=args.ollama_port),
                trigger=QUESTION, component_name="asker")
    checker = Checker(OllamaClient(model, port=args.ollama_port))
    launcher = Launcher(transport=args.transport, transport_options=transport_options(args.transport, args.listen))
    launcher.add_pkg(components=[asker, checker], multiprocessing=True)
    serve(launcher)


if __name__ == "__main__":
    main()
