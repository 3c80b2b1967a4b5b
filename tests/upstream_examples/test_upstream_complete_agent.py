"""Upstream's complete_agent examples (tag 0.6.0): nine components, every stand-in server, inputs fed, outputs checked.

``complete_agent.py`` runs in this process on memory; ``complete_agent_multiprocessing.py`` (one
process per component upstream) runs as a script on Zenoh. Both speak on the robot
(``play_on_device=True``): the sound card is :mod:`sound_device_standin`. Upstream's ``trigger=15.0``
is a rate here (the recipe keeps upstream's value); the tests run the timed components at 2 Hz
through ``UPSTREAM_TRIGGER``.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core.messages import AudioMsg, Header, OccupancyGridMsg, OdometryMsg, PoseMsg
from agents_core.ros import Topic

from ..clients.test_chroma_client import chroma_port  # noqa: F401  (a fixture, used by name)
from ..conftest import wait_for
from ..servers.ollama_server import OllamaTestServer
from ..servers.roboml_server import RoboMLTestServer
from .harness import RECIPES, launched_as_script, launched_here
from .sound_device_standin import sounddevice as sound

V060 = RECIPES / "v0_6_0"
SOUND_STANDIN = Path(__file__).resolve().parent / "sound_device_standin"
OLLAMA_MODELS = ["qwen2.5vl:latest", "llama3.2:3b", "bge-large:latest"]
QUESTION = "What is the capital of France?"  # one of the chat route's own samples


@pytest.fixture
def servers(chroma_port: int, monkeypatch: pytest.MonkeyPatch) -> Iterator[dict[str, Any]]:  # noqa: F811
    """The stand-ins' ports, as the recipes read them, with the timed components at 2 Hz."""
    with OllamaTestServer(models=OLLAMA_MODELS) as ollama, RoboMLTestServer() as roboml:
        monkeypatch.setenv("OLLAMA_HOST", f"127.0.0.1:{ollama.port}")  # ChromaDB()'s embeddings
        yield {"UPSTREAM_OLLAMA_PORT": ollama.port, "UPSTREAM_ROBOML_PORT": roboml.port,
               "UPSTREAM_ROBOML_RESP_PORT": roboml.resp_port, "UPSTREAM_CHROMA_PORT": chroma_port,
               "UPSTREAM_TRIGGER": "2.0", "OLLAMA_HOST": f"127.0.0.1:{ollama.port}"}


def _collect(transport: Any, name: str, msg_type: str) -> list[Any]:
    got: list[Any] = []
    transport.create_subscription(Topic(name=name, msg_type=msg_type), got.append)
    return got


def _robot_inputs() -> list[tuple[Topic, Any]]:
    """What a robot keeps publishing: its map, where it is on it, and the camera."""
    grid = OccupancyGridMsg(data=np.zeros((40, 40), np.int8), resolution=0.5,
                            origin=PoseMsg(position=[-10.0, -10.0, 0.0]), header=Header(frame_id="map"))
    odom = OdometryMsg(pose=PoseMsg(position=[1.0, 2.0, 0.0]), header=Header(frame_id="map"))
    image = np.random.default_rng(7).integers(0, 255, size=(48, 64, 3), dtype=np.uint8)
    return [(Topic(name="map", msg_type="OccupancyGrid"), grid), (Topic(name="odom", msg_type="Odometry"), odom),
            (Topic(name="image_raw", msg_type="Image"), image)]


def _map_documents(port: int, layer: str) -> list[str]:
    """The documents MapEncoding wrote into the Chroma collection ``map`` for ``layer``."""
    from agents_core.clients import ChromaClient  # noqa: PLC0415
    from agents_core.vectordbs import ChromaDB  # noqa: PLC0415

    client = ChromaClient(ChromaDB(), port=port)
    client.initialize()
    try:
        found = client.metadata_query({"collection_name": "map", "where": {"layer": layer}})
    except Exception:  # the collection does not exist until the first write
        return []
    finally:
        client.deinitialize()
    return list(found.get("documents") or [])


def _feed_until(transport: Any, done: Any, *, question: bool, timeout: float) -> bool:
    """Publish the robot's inputs (and the question) every second until ``done()``."""
    feeds = [(transport.create_publisher(topic), value) for topic, value in _robot_inputs()]
    if question:
        feeds.append((transport.create_publisher(Topic(name="question", msg_type="String")), QUESTION))

    def fed() -> bool:
        for pub, value in feeds:
            pub.publish(value)
        return bool(done())

    try:
        return wait_for(fed, timeout=timeout, interval=1.0)
    finally:
        for pub, _ in feeds:
            pub.close()


def test_complete_agent_in_one_process(servers: dict[str, Any], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "sounddevice", sound)  # TextToSpeech imports it at configure
    sound.played.clear()
    chroma = int(servers["UPSTREAM_CHROMA_PORT"])
    with launched_here(V060 / "complete_agent.py", servers, monkeypatch, timeout=120) as launcher:
        t = launcher.transport
        transcripts, answers = _collect(t, "question", "String"), _collect(t, "answer", "String")
        boxes, rooms = _collect(t, "detections", "Detections"), _collect(t, "introspection_answer", "String")
        t.create_publisher(Topic(name="audio0", msg_type="Audio")).publish(
            AudioMsg(data=np.zeros(16000, dtype=np.int16), sample_rate=16000))
        assert wait_for(lambda: bool(transcripts), timeout=30)  # Whisper heard it and the router got it
        assert _feed_until(t, lambda: QUESTION in "".join(answers) and sound.played and boxes and rooms
                           and _map_documents(chroma, "detections") and _map_documents(chroma, "introspection_answer"),
                           question=True, timeout=90), (answers, sound.played, boxes, rooms)
    assert set(rooms) <= {"office", "bedroom", "kitchen"}  # the pre-processor published one word or nothing
    assert _map_documents(chroma, "introspection_answer")[0] in {"office", "bedroom", "kitchen"}


@pytest.mark.zenoh
def test_complete_agent_multiprocessing_on_zenoh(servers: dict[str, Any], tmp_path: Path) -> None:
    # Every component process finds the sound card stand-in first on its path.
    env = {**servers, "PYTHONPATH": os.pathsep.join([str(SOUND_STANDIN), os.environ.get("PYTHONPATH", "")])}
    chroma = int(servers["UPSTREAM_CHROMA_PORT"])
    with launched_as_script(V060 / "complete_agent_multiprocessing.py", env, tmp_path) as (proc, asker):
        answers, boxes = _collect(asker, "answer", "String"), _collect(asker, "detections", "Detections")
        assert _feed_until(asker, lambda: proc.proc.poll() is not None or (
            QUESTION in "".join(answers) and boxes and "The door is here. DOOR." in _map_documents(
                chroma, "introspection_answer")), question=True, timeout=180)
        assert proc.proc.poll() is None, "the recipe exited"
