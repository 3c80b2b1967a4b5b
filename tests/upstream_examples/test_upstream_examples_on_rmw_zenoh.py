"""Upstream's event-driven and conversational recipes on the rmw_zenoh transport, only the transport name changed.

The recipe file runs unchanged as a script with ``AGENTS_TRANSPORT=rmw_zenoh``; its sessions reach a router (a
child process) through rmw_zenoh's own ``ZENOH_CONFIG_OVERRIDE``, in ROS domain 21; the asker is an rmw_zenoh
transport on the same router.
"""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core.messages import AudioMsg
from agents_core.ros import Topic
from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.recipes import RecipeProcess, recipe_environment

from ..conftest import wait_for
from ..servers.ollama_server import OllamaTestServer
from ..servers.roboml_server import RoboMLTestServer
from .test_upstream_examples import OLLAMA_MODELS, V074, _collect, _image, _person_photo, _ports, _ssd_ports

pytest.importorskip("rosbags", reason="needs the rmw_zenoh extra")
pytest.importorskip("agents_interfaces", reason="needs agents_interfaces")

pytestmark = [pytest.mark.zenoh, pytest.mark.slow]

from agents_zenoh.rmw.transport import RmwZenohTransport  # noqa: E402

ROUTER = Path(__file__).resolve().parents[1] / "rmw_zenoh" / "router.py"


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
    port = free_tcp_port()
    router = subprocess.Popen([sys.executable, str(ROUTER), str(port)], stdout=subprocess.PIPE, text=True,
                              env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    endpoint = f"tcp/127.0.0.1:{port}"
    process = None
    asker = None
    try:
        assert router.stdout is not None and router.stdout.readline().strip() == "ready"
        env = recipe_environment(AGENTS_TRANSPORT="rmw_zenoh", ROS_DOMAIN_ID="21",
                                 ZENOH_CONFIG_OVERRIDE=f'connect/endpoints=["{endpoint}"];'
                                                       'listen/endpoints=["tcp/127.0.0.1:0"]',
                                 **{k: str(v) for k, v in ports.items()})
        process = RecipeProcess(recipe, [], tmp_path / "recipe.log", cwd=recipe.parent, env=env)
        asker = RmwZenohTransport(connect=[endpoint], listen=["tcp/127.0.0.1:0"], domain_id=21)
        try:
            yield process, asker
        except BaseException:
            raise AssertionError(f"recipe {recipe.name} on rmw_zenoh:\n{process.output()}") from None
    finally:
        if asker is not None:
            asker.close()
        if process is not None:
            process.stop()
        router.terminate()
        try:
            router.wait(timeout=10)
        except subprocess.TimeoutExpired:
            router.kill()
            router.wait()
        if router.stdout is not None:
            router.stdout.close()


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
