"""The same LLM recipe file (llm_recipe.py) answers on memory, zenoh and ros2.

Memory runs in this process; on each cross-process transport (the ``recipe_transport`` fixture)
the recipe runs in a child process (stopped by PID afterwards) and this one asks through the
framework's own transport. Transports whose extra is missing are skipped with the reason.
"""

from __future__ import annotations

import threading
from pathlib import Path

import pytest

from agents_core import Launcher
from agents_core.messages import StreamingStringMsg
from agents_core.testing.recipes import RecipeTransport, run_recipe
from agents_core.transport.contract import Transport

from ..conftest import wait_for
from . import llm_recipe
from .models_dir import REPO, needs_smollm2

pytestmark = pytest.mark.local_models


def _ask(transport: Transport, question: str, attempts: int = 4) -> list[StreamingStringMsg]:
    chunks: list[StreamingStringMsg] = []
    done = threading.Event()

    def on_chunk(msg: StreamingStringMsg) -> None:
        chunks.append(msg)
        if msg.done:
            done.set()

    sub = transport.create_subscription(llm_recipe.ANSWER, on_chunk)
    pub = transport.create_publisher(llm_recipe.QUESTION)
    try:
        # Across processes the first sample can precede discovery; ask again, a bounded number of times.
        for _ in range(attempts):
            pub.publish(question)
            if wait_for(lambda: bool(chunks), timeout=10):
                break
        assert done.wait(60), f"no complete answer; got {len(chunks)} chunks"
    finally:
        pub.close()
        sub.close()
    return chunks


def _check(chunks: list[StreamingStringMsg]) -> None:
    first_answer: list[StreamingStringMsg] = []
    for c in chunks:
        first_answer.append(c)
        if c.done:
            break
    text = "".join(c.data for c in first_answer)
    assert len(first_answer) >= 3 and text.strip(), text


def test_recipe_on_memory() -> None:
    needs_smollm2()
    launcher = Launcher("memory")
    launcher.add_pkg(components=[llm_recipe.build()])
    with launcher:
        _check(_ask(launcher.transport, "What is the capital of France?"))


def test_recipe_in_its_own_process(recipe_transport: RecipeTransport, tmp_path: Path) -> None:
    needs_smollm2()
    with run_recipe("tests.components.llm_recipe", recipe_transport, tmp_path, cwd=REPO):
        _check(_ask(recipe_transport.open_asker(), "What is the capital of France?"))
