"""Upstream's event-driven and conversational recipes on the rmw_zenoh transport, only the transport name changed.

The recipe file runs unchanged as a script with ``AGENTS_TRANSPORT=rmw_zenoh`` (:func:`run_recipe`); its sessions
reach the recipe harness's router (a child process) through rmw_zenoh's own ``ZENOH_CONFIG_OVERRIDE``; the asker is
an rmw_zenoh transport on the same router.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core.messages import AudioMsg
from agents_core.ros import Topic
from agents_core.testing.recipes import RecipeProcess, open_recipe_transport, run_recipe

from ..conftest import wait_for
from ..servers.ollama_server import OllamaTestServer
from ..servers.roboml_server import RoboMLTestServer
from .test_upstream_examples import OLLAMA_MODELS, V074, _collect, _image, _person_photo, _ports, _ssd_ports

pytest.importorskip("rosbags", reason="needs the rmw_zenoh extra")
pytest.importorskip("agents_interfaces", reason="needs agents_interfaces")

pytestmark = [pytest.mark.zenoh, pytest.mark.slow]


@pytest.fixture
def ollama() -> Iterator[OllamaTestServer]:
    with OllamaTestServer(models=OLLAMA_MODELS) as server:
        yield server


@pytest.fixture
def roboml() -> Iterator[RoboMLTestServer]:
    with RoboMLTestServer() as server:
        yield server


@contextmanager
def _on_rmw_zenoh(recipe: Path, ports: Mapping[str, Any], tmp_path: Path) -> Iterator[tuple[RecipeProcess, Any]]:
    """The recipe unchanged, on the recipe harness's router (its own ZENOH_CONFIG_OVERRIDE), and an asker there."""
    harness = open_recipe_transport("rmw_zenoh")
    try:
        with run_recipe(recipe, harness, tmp_path, cwd=recipe.parent, ready_timeout=None, transport_args=False,
                        env={"AGENTS_TRANSPORT": "rmw_zenoh", **{k: str(v) for k, v in ports.items()}}) as process:
            yield process, harness.open_asker()
    finally:
        harness.end()


def test_event_driven_visual_description_on_rmw_zenoh(ollama: OllamaTestServer, tmp_path: Path) -> None:
    picture = _person_photo()
    empty = np.zeros_like(picture)
    with _on_rmw_zenoh(V074 / "event_driven_visual_description.py", _ssd_ports(ollama), tmp_path) as (proc, asker):
        descriptions = _collect(asker, "/description", "String")
        shown = (empty if i % 7 == 6 else picture for i in itertools.count())
        pub = asker.create_publisher(Topic(name="/image_raw", msg_type="Image"))
        try:
            assert wait_for(lambda: bool(descriptions) or proc.proc.poll() is not None
                            or (pub.publish(next(shown)), False)[1], timeout=180, interval=1.0)
        finally:
            pub.close()
        assert descriptions
    assert "say briefly what they look like" in descriptions[0]


def test_conversational_agent_on_rmw_zenoh(ollama: OllamaTestServer, roboml: RoboMLTestServer,
                                           tmp_path: Path) -> None:
    recipe = V074 / "conversational_agent_with_audio.py"
    with _on_rmw_zenoh(recipe, _ports(ollama, roboml), tmp_path) as (proc, asker):
        transcripts, replies = _collect(asker, "text0", "String"), _collect(asker, "text1", "String")
        image = asker.create_publisher(Topic(name="image_raw", msg_type="Image"))
        audio = asker.create_publisher(Topic(name="audio0", msg_type="Audio"))
        assert wait_for(lambda: bool(replies) or proc.proc.poll() is not None
                        or (image.publish(_image()), audio.publish(AudioMsg(data=np.zeros(16000, dtype=np.int16),
                                                                            sample_rate=16000)), False)[2],
                        timeout=180, interval=3.0)
        assert replies
    assert transcripts and "".join(replies).startswith("You said: " + transcripts[0][:10]), (transcripts, replies)
