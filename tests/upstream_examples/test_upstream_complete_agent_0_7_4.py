"""Upstream's complete_agent examples (tag 0.7.4): nine components with Memory, every stand-in server, inputs fed.

``complete_agent.py`` runs in this process on memory; ``complete_agent_multiprocessing.py`` runs on
Zenoh with one process per component, as upstream asks (``multiprocessing=True``). The robot's
inputs are fed as a robot would keep publishing them (map, odometry, a camera photo) and each chain
is checked at its end: speech in -> a transcript; a question -> the router -> an answer, spoken on
the (stand-in) sound card; camera -> detections and the room word -> observations in the memory's
database at the robot's place; "go to X" -> the go-to-X model's ``locate`` tool call on Memory ->
a goal point at the place the memory has for it. The Ollama stand-in answers every request that
offers tools with a ``locate`` call, so only the go-to-X model calls it.
"""

from __future__ import annotations

import contextlib
import sqlite3
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core.messages import AudioMsg, Header, OccupancyGridMsg, OdometryMsg, PoseMsg
from agents_core.ros import Topic
from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.pairs import skip_unless_installed

from ..clients.test_chroma_client import chroma_port  # noqa: F401  (a fixture, used by name)
from ..conftest import wait_for
from ..servers.ollama_server import OllamaTestServer
from ..servers.roboml_server import RoboMLTestServer
from .harness import RECIPES, launched_here, launched_in_processes
from .sound_device_standin import sounddevice as sound

V074 = RECIPES / "v0_7_4"
SOUND_STANDIN = Path(__file__).resolve().parent / "sound_device_standin"
SHARED_IMAGES = Path(__file__).resolve().parents[2].parent / "shared" / "images"
# bge-large: the embeddings of ChromaDB() (the router's routes), through the same Ollama.
OLLAMA_MODELS = ["qwen2.5vl:latest", "qwen3:0.6b", "nomic-embed-text-v2-moe:latest", "bge-large:latest"]
QUESTION = "What is the capital of France?"  # one of the chat route's own samples
GOTO = "Go to the kitchen"  # one of the go-to route's own samples
#: Where the fed odometry puts the robot (away from the origin, so a goal there is not a default).
ROBOT_AT = (3.5, -1.5, 0.0)
ROOMS = {"office", "bedroom", "kitchen"}


@pytest.fixture
def servers(chroma_port: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[dict[str, Any]]:  # noqa: F811
    """The stand-ins' ports and the memory's folder, as the recipes read them, with the timed components at 2 Hz."""
    skip_unless_installed("memory", "emem", reason="the Memory component needs emem (the memory extra)")
    # Whatever offers tools is answered with a call to Memory.locate (only the go-to-X model offers tools).
    with OllamaTestServer(models=OLLAMA_MODELS, tool_calls=[{"name": "locate", "arguments": {"concept": "office"}}]
                          ) as ollama, RoboMLTestServer() as roboml:
        monkeypatch.setenv("OLLAMA_HOST", f"127.0.0.1:{ollama.port}")  # ChromaDB()'s embeddings
        yield {"UPSTREAM_OLLAMA_PORT": ollama.port, "UPSTREAM_ROBOML_PORT": roboml.port,
               "UPSTREAM_ROBOML_RESP_PORT": roboml.resp_port, "UPSTREAM_CHROMA_PORT": chroma_port,
               "UPSTREAM_TRIGGER": "2.0", "OLLAMA_HOST": f"127.0.0.1:{ollama.port}",
               "UPSTREAM_MEMORY_DIR": str(tmp_path), "ollama": ollama}


def _ports(servers: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in servers.items() if k.isupper()}


def _camera_frame() -> np.ndarray:
    """A shared photo, made small (the stand-ins only look at its size), or random pixels without one."""
    path = SHARED_IMAGES / "coffee.png"
    if not path.is_file():
        return np.random.default_rng(7).integers(0, 255, size=(48, 64, 3), dtype=np.uint8)
    from PIL import Image as PILImage  # noqa: PLC0415

    with PILImage.open(path) as img:
        return np.asarray(img.convert("RGB").resize((64, 48)))


def _robot_inputs() -> list[tuple[Topic, Any]]:
    """What a robot keeps publishing: its map, where it is on it, and the camera."""
    grid = OccupancyGridMsg(data=np.zeros((40, 40), np.int8), resolution=0.5,
                            origin=PoseMsg(position=[-10.0, -10.0, 0.0]), header=Header(frame_id="map"))
    odom = OdometryMsg(pose=PoseMsg(position=list(ROBOT_AT)), header=Header(frame_id="map"))
    return [(Topic(name="map", msg_type="OccupancyGrid"), grid), (Topic(name="odom", msg_type="Odometry"), odom),
            (Topic(name="image_raw", msg_type="Image"), _camera_frame())]


def _collect(transport: Any, name: str, msg_type: str) -> list[Any]:
    got: list[Any] = []
    transport.create_subscription(Topic(name=name, msg_type=msg_type), got.append)
    return got


def _observations(db: Path) -> list[tuple[str, str, float, float]]:
    """(layer, text, x, y) of every observation in the memory's database (read-only, while it runs)."""
    if not db.is_file():
        return []
    with contextlib.closing(sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=1.0)) as con:
        try:
            return list(con.execute("SELECT layer_name, text, x, y FROM observations"))
        except sqlite3.OperationalError:  # the table is made at the first open
            return []


def _remembers_room_and_objects(db: Path) -> bool:
    layers = {(layer, text) for layer, text, _, _ in _observations(db)}
    return any(layer == "introspection_answer" and text in ROOMS for layer, text in layers) and any(
        layer == "detections" for layer, _ in layers)


def _feed_until(transport: Any, done: Any, *, asks: list[str], timeout: float) -> bool:
    """Publish the robot's inputs (and each question in ``asks``) every second until ``done()``."""
    feeds = [(transport.create_publisher(topic), value) for topic, value in _robot_inputs()]
    question = transport.create_publisher(Topic(name="question", msg_type="String"))

    def fed() -> bool:
        for pub, value in feeds:
            pub.publish(value)
        for text in asks:
            question.publish(text)
        return bool(done())

    try:
        return wait_for(fed, timeout=timeout, interval=1.0)
    finally:
        for pub, _ in feeds:
            pub.close()
        question.close()


def _at_robot(goal: Any) -> bool:
    return bool(np.allclose(np.asarray(goal.position, dtype=float), ROBOT_AT, atol=0.05))


def test_complete_agent_in_one_process(servers: dict[str, Any], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "sounddevice", sound)  # TextToSpeech imports it at configure
    sound.played.clear()
    db = Path(servers["UPSTREAM_MEMORY_DIR"]) / "complete_agent.db"
    with launched_here(V074 / "complete_agent.py", _ports(servers), monkeypatch, timeout=120) as launcher:
        t = launcher.transport
        transcripts, answers = _collect(t, "question", "String"), _collect(t, "answer", "String")
        goals, rooms = _collect(t, "goal_point", "PoseStamped"), _collect(t, "introspection_answer", "String")
        t.create_publisher(Topic(name="audio0", msg_type="Audio")).publish(
            AudioMsg(data=np.zeros(16000, dtype=np.int16), sample_rate=16000))
        assert wait_for(lambda: bool(transcripts), timeout=30)  # Whisper heard it and the router got it
        assert "heard 16000 samples" in transcripts
        # First the memory fills (a room word and the detections, where the robot stands) ...
        assert _feed_until(t, lambda: _remembers_room_and_objects(db) and QUESTION in "".join(answers)
                           and sound.played, asks=[QUESTION], timeout=90), (
            _observations(db), answers, len(sound.played))
        # ... then "go to the kitchen" is routed to the go-to-X model, whose locate call finds the place.
        assert _feed_until(t, lambda: any(_at_robot(g) for g in goals), asks=[GOTO], timeout=60), goals
    assert set(rooms) <= ROOMS  # the pre-processor published one word or nothing
    stored = _observations(db)
    assert stored and all(np.allclose((x, y), ROBOT_AT[:2]) for _, _, x, y in stored), stored
    chats = [r for r in servers["ollama"].requests_to("/api/chat") if r.json.get("tools")]
    assert chats and all([tool["function"]["name"] for tool in r.json["tools"]] == ["locate"] for r in chats)
    assert any(GOTO in m.get("content", "") for m in chats[0].json["messages"])  # the go-to prompt, rendered


@pytest.mark.zenoh
def test_complete_agent_multiprocessing_on_zenoh(servers: dict[str, Any], tmp_path: Path) -> None:
    skip_unless_installed("ui", "uvicorn", reason="the recipe serves the web UI (the ui extra)")
    # Every component process finds the sound card stand-in first on its path.
    env = {"PYTHONPATH": str(SOUND_STANDIN)}
    ports = {**_ports(servers), "UPSTREAM_UI_PORT": free_tcp_port()}
    db = Path(servers["UPSTREAM_MEMORY_DIR"]) / "complete_agent_multiprocessing.db"
    with launched_in_processes(V074 / "complete_agent_multiprocessing.py", ports, tmp_path, env=env,
                               ready_timeout=240) as (proc, asker):
        answers, goals = _collect(asker, "answer", "String"), _collect(asker, "goal_point", "PoseStamped")
        assert _feed_until(asker, lambda: proc.proc.poll() is not None or (
            _remembers_room_and_objects(db) and QUESTION in "".join(answers)), asks=[QUESTION], timeout=180), (
            _observations(db), answers)
        # The go-to-X model's process calls locate on the memory's process (its execute_method service).
        assert _feed_until(asker, lambda: proc.proc.poll() is not None or any(_at_robot(g) for g in goals),
                           asks=[GOTO], timeout=90), goals
        assert proc.proc.poll() is None, "the recipe exited"
        # The web UI answers on the port the recipe was given.
        import httpx  # noqa: PLC0415

        assert httpx.get(f"http://127.0.0.1:{ports['UPSTREAM_UI_PORT']}/", timeout=10).status_code == 200
    stored = _observations(db)
    assert stored and all(np.allclose((x, y), ROBOT_AT[:2]) for _, _, x, y in stored), stored
