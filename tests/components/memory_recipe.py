"""A Memory recipe run in a process of its own by test_memory_hardening.py (crash, lock and Zenoh tests).

``python -m tests.components.memory_recipe --transport memory --db PATH --notes 20`` brings up a
Memory (component name ``memory``) on the database at PATH whose embeddings come from
:class:`WordEmbedder` (hashed bags of words, no server), writes ``--notes`` notes through
``store_specific_memory`` (each committed before the call returns), prints ``COMMITTED n`` and
``READY`` on stdout and runs until SIGINT / SIGTERM (or SIGKILL, which is the point of some tests).
``--transport zenoh --listen tcp/127.0.0.1:PORT`` (or ``--transport ros2``, discovery settings from the
environment) serves it to a peer in another process.
"""

from __future__ import annotations

import argparse
import hashlib
import logging
import re
import signal
import sys
import threading
from collections.abc import MutableMapping
from typing import Any

from agents_core import Launcher, Topic
from agents_core.clients import ModelClient
from agents_core.components import MemLayer, Memory
from agents_core.config import MemoryConfig
from agents_core.errors import ComponentError
from agents_core.models import GenericLLM

from .recipe_main import MAX_RUN_SECONDS, transport_options

ODOM, HEARD = Topic("odom", "Odometry"), Topic("heard", "String")
#: A word per note: the notes are told apart by meaning.
WORDS = ("apple", "banana", "cherry", "damson", "elder", "fig", "grape", "hazel", "iris", "juniper", "kiwi", "lemon",
         "mango", "nectarine", "olive", "peach", "quince", "raspberry", "sloe", "tangerine", "ugli", "vanilla",
         "walnut", "xigua", "yuzu", "zucchini", "almond", "basil", "clove", "dill")


def note(i: int, writer: str = "") -> str:
    """The text of note ``i`` (of ``writer``): its own word, and shared ones."""
    return f"{writer}note about the {WORDS[i % len(WORDS)]}{i // len(WORDS) or ''} in the pantry"


class WordEmbedder(ModelClient):
    """Embeddings as hashed bags of words (``dim`` values); its checkpoint names the model."""

    def __init__(self, dim: int = 64, checkpoint: str = "words") -> None:
        super().__init__(model=GenericLLM(name="words", checkpoint=checkpoint))
        self.dim = dim

    def _check_connection(self) -> None: ...
    def _initialize(self) -> None: ...
    def _deinitialize(self) -> None: ...

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        raise NotImplementedError

    def _embed(self, texts: list[str]) -> list[list[float]]:
        vectors = []
        for text in texts:
            v = [0.0] * self.dim
            for word in re.findall(r"[a-z0-9]+", text.lower()):
                v[int(hashlib.md5(word.encode()).hexdigest(), 16) % self.dim] += 1.0
            v[-1] += 0.01  # never the zero vector (cosine space)
            vectors.append(v)
        return vectors


def build(db: str, dim: int = 64, checkpoint: str = "words", **config: Any) -> Memory:
    """The recipe's Memory on ``db``."""
    config.setdefault("flush_interval", 0.0)
    return Memory(layers=[MemLayer(subscribes_to=HEARD, temporal_change=True)], position=ODOM,
                  embedding_client=WordEmbedder(dim, checkpoint), config=MemoryConfig(db_path=db, **config),
                  trigger=20.0, component_name="memory")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--transport", required=True, choices=["memory", "zenoh", "ros2", "rmw_zenoh"])
    parser.add_argument("--listen", default=None, help="zenoh: the endpoint to listen on")
    parser.add_argument("--db", required=True)
    parser.add_argument("--notes", type=int, default=0)
    parser.add_argument("--writer", default="")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, stream=sys.stderr, format="%(levelname)s %(name)s: %(message)s")
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    memory = build(args.db)
    launcher = Launcher(transport=args.transport, transport_options=transport_options(args.transport, args.listen))
    launcher.add_pkg(components=[memory])
    with launcher:
        try:
            for i in range(args.notes):
                memory.store_specific_memory(note(i, args.writer), x=float(i), y=0.0)
            print(f"COMMITTED {memory.stats['stored']}", flush=True)
        except ComponentError as exc:  # e.g. another process holds the database
            print(f"REFUSED {exc}", flush=True)
        print("READY", flush=True)
        stop.wait(MAX_RUN_SECONDS)
    print("stopped cleanly", file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
