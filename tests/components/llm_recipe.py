"""One LLM recipe, run unchanged on every transport by test_llm_recipe_transports.py.

``python -m tests.components.llm_recipe --transport zenoh --listen tcp/127.0.0.1:PORT`` (or
``--transport ros2``, discovery settings from the environment) brings up an LLM component on
the local SmolLM2 model: ``question`` (String) in, ``answer`` (StreamingString) out. It prints
``READY`` on stdout once active and runs until SIGTERM / SIGINT.
"""

from __future__ import annotations

import argparse

from agents_core import Launcher, Topic
from agents_core.components import LLM
from agents_core.config import LLMConfig

from .recipe_main import serve, transport_options

QUESTION = Topic("question", "String")
ANSWER = Topic("answer", "StreamingString")


def build() -> LLM:
    """The recipe's one component (the part that is the same on every transport)."""
    config = LLMConfig(enable_local_model=True, stream=True, temperature=0.0, max_new_tokens=16,
                       system_prompt="You are a helpful robot.")
    return LLM(inputs=[QUESTION], outputs=[ANSWER], config=config, trigger=QUESTION, component_name="assistant")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--transport", required=True, choices=["memory", "zenoh", "ros2", "rmw_zenoh"])
    parser.add_argument("--listen", default=None, help="zenoh: the endpoint to listen on")
    args = parser.parse_args(argv)
    launcher = Launcher(transport=args.transport, transport_options=transport_options(args.transport, args.listen))
    launcher.add_pkg(components=[build()])
    serve(launcher)


if __name__ == "__main__":
    main()
