"""Upstream EmbodiedAgents' examples (tags 0.6.0 and 0.7.4), written again with the same API calls, run here.

Each recipe under ``recipes/`` names the upstream file it mirrors. A test starts the local stand-ins
for its model servers, runs the recipe unchanged (in this process on memory; where the recipe asks
for ``multiprocessing=True``, also as a script on Zenoh), feeds its inputs and checks its outputs.
A recipe blocked by a known difference from upstream (issue 26) is ``xfail(strict=True)``: the
day the difference is fixed it passes, the strict mark fails, and the mark is removed.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core.ros import Topic

from ..conftest import wait_for
from ..servers.ollama_server import OllamaTestServer
from ..servers.roboml_server import RoboMLTestServer
from .harness import RECIPES, launched_here

V060, V074 = RECIPES / "v0_6_0", RECIPES / "v0_7_4"

#: Every model name the recipes ask the Ollama stand-in for.
OLLAMA_MODELS = ["qwen2.5vl:latest", "qwen2.5vl:7b", "llama3.2:3b", "qwen3:0.6b"]


def _issue26(difference: str) -> Any:
    return pytest.mark.xfail(strict=True, reason=f"issue 26: {difference}")


@pytest.fixture
def ollama() -> Iterator[OllamaTestServer]:
    with OllamaTestServer(models=OLLAMA_MODELS) as server:
        yield server


@pytest.fixture
def roboml() -> Iterator[RoboMLTestServer]:
    with RoboMLTestServer() as server:
        yield server


def _ports(ollama: OllamaTestServer | None = None, roboml: RoboMLTestServer | None = None,
           chroma: int | None = None) -> dict[str, int]:
    ports: dict[str, int] = {}
    if ollama is not None:
        ports["UPSTREAM_OLLAMA_PORT"] = ollama.port
    if roboml is not None:
        ports["UPSTREAM_ROBOML_PORT"] = roboml.port
        ports["UPSTREAM_ROBOML_RESP_PORT"] = roboml.resp_port
    if chroma is not None:
        ports["UPSTREAM_CHROMA_PORT"] = chroma
    return ports


def _collect(transport: Any, name: str, msg_type: str) -> list[Any]:
    got: list[Any] = []
    transport.create_subscription(Topic(name=name, msg_type=msg_type), got.append)
    return got


def _image() -> np.ndarray:
    rng = np.random.default_rng(7)
    return rng.integers(0, 255, size=(48, 64, 3), dtype=np.uint8)


# -- prompt engineering -------------------------------------------------------------------------------


@pytest.mark.parametrize("recipe", [V060 / "prompt_engineering.py", V074 / "prompt_engineering.py"],
                         ids=["0.6.0", "0.7.4"])
def test_prompt_engineering(recipe: Path, ollama: OllamaTestServer, roboml: RoboMLTestServer,
                            monkeypatch: pytest.MonkeyPatch) -> None:
    with launched_here(recipe, _ports(ollama, roboml), monkeypatch) as launcher:
        t = launcher.transport
        detections, answers = _collect(t, "detections", "Detections"), _collect(t, "text1", "String")
        t.create_publisher(Topic(name="image_raw", msg_type="Image")).publish(_image())
        assert wait_for(lambda: bool(detections), timeout=30)
        t.create_publisher(Topic(name="text0", msg_type="String")).publish("What is on the table?")
        assert wait_for(lambda: bool(answers), timeout=30)
    print(answers[0], detections[0])
    assert "Question about it: What is on the table?" in answers[0]
