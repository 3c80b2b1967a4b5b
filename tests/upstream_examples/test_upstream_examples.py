"""Upstream EmbodiedAgents' examples (tags 0.6.0 and 0.7.4), written again with the same API calls, run here.

Each recipe under ``recipes/`` names the upstream file it mirrors. A test starts the local stand-ins
for its model servers, runs the recipe unchanged (in this process on memory; where the recipe asks
for ``multiprocessing=True``, also as a script on Zenoh), feeds its inputs and checks its outputs.
A recipe blocked by a known difference from upstream (issue 26) is ``xfail(strict=True)``: the
day the difference is fixed it passes, the strict mark fails, and the mark is removed.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core.messages import AudioMsg
from agents_core.ros import Topic

from ..clients.test_chroma_client import chroma_port  # noqa: F401  (a fixture, used by name)
from ..components.models_dir import needs_smollm2
from ..conftest import wait_for
from ..servers.ollama_server import OllamaTestServer
from ..servers.roboml_server import RoboMLTestServer
from .harness import RECIPES, ask_until, launched_as_script, launched_here

V060, V074 = RECIPES / "v0_6_0", RECIPES / "v0_7_4"

#: Every model name the recipes ask the Ollama stand-in for.
OLLAMA_MODELS = ["qwen2.5vl:latest", "qwen2.5vl:7b", "llama3.2:3b", "qwen3:0.6b", "bge-large:latest"]


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
    assert "Items detected in it: object." in answers[0]
    assert "Question about it: What is on the table?" in answers[0]


# -- conversational agent with audio ------------------------------------------------------------------


# 0.6.0's variant (SpeechT5, VAD, playback on the device) is test_upstream_audio_0_6_0.py.
@pytest.mark.parametrize("recipe", [pytest.param(V074 / "conversational_agent_with_audio.py", id="0.7.4")])
def test_conversational_agent_with_audio(recipe: Path, ollama: OllamaTestServer, roboml: RoboMLTestServer,
                                         monkeypatch: pytest.MonkeyPatch) -> None:
    with launched_here(recipe, _ports(ollama, roboml), monkeypatch) as launcher:
        t = launcher.transport
        transcripts, replies = _collect(t, "text0", "String"), _collect(t, "text1", "String")
        spoken = _collect(t, "audio_out", "Audio")
        t.create_publisher(Topic(name="image_raw", msg_type="Image")).publish(_image())
        t.create_publisher(Topic(name="audio0", msg_type="Audio")).publish(
            AudioMsg(data=np.zeros(16000, dtype=np.int16), sample_rate=16000))
        assert wait_for(lambda: bool(replies), timeout=30), (transcripts, replies)
        if "v0_7_4" in str(recipe):  # 0.6.0 plays the speech on the device and publishes none
            assert wait_for(lambda: bool(spoken), timeout=30)
    assert transcripts and "".join(replies).startswith("You said: " + transcripts[0][:10]), (transcripts, replies)


# -- model fallbacks (multiprocessing=True upstream) ----------------------------------------------------


def _ask_brain(transport: Any, answers: list[str], process: Any = None) -> bool:
    # A recipe process that exited ends the wait at once (its output is in the failure).
    return ask_until(transport, Topic(name="user_query", msg_type="String"), "What colour is the sky?",
                     lambda: bool(answers) or (process is not None and process.proc.poll() is not None),
                     timeout=90) and bool(answers)


def test_model_client_fallback_in_one_process(ollama: OllamaTestServer, roboml: RoboMLTestServer,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    roboml.set_fault("error", times=1000)  # the remote model fails every inference
    with launched_here(RECIPES / "model_client_fallback.py", _ports(ollama, roboml), monkeypatch) as launcher:
        answers = _collect(launcher.transport, "llm_response", "String")
        assert _ask_brain(launcher.transport, answers)
    assert "".join(answers).startswith("You said:"), answers  # the Ollama spare answered
    assert ollama.requests_to("/api/chat")


@pytest.mark.zenoh
def test_model_client_fallback_on_zenoh(ollama: OllamaTestServer, roboml: RoboMLTestServer, tmp_path: Path) -> None:
    roboml.set_fault("error", times=1000)
    with launched_as_script(RECIPES / "model_client_fallback.py", _ports(ollama, roboml), tmp_path) as (proc, asker):
        answers = _collect(asker, "llm_response", "String")
        assert _ask_brain(asker, answers, proc)
    assert "".join(answers).startswith("You said:"), answers


def test_model_client_fallback_when_the_remote_server_is_down_at_start(
        ollama: OllamaTestServer, monkeypatch: pytest.MonkeyPatch) -> None:
    down = RoboMLTestServer().start()
    ports = _ports(ollama, down)
    down.stop()  # upstream: the switch happens "if the initial model setup fails"
    with launched_here(RECIPES / "model_client_fallback.py", ports, monkeypatch) as launcher:
        answers = _collect(launcher.transport, "llm_response", "String")
        assert _ask_brain(launcher.transport, answers)
    assert "".join(answers).startswith("You said:"), answers


def test_local_model_fallback_in_one_process(roboml: RoboMLTestServer, monkeypatch: pytest.MonkeyPatch) -> None:
    needs_smollm2()
    roboml.set_fault("error", times=1000)
    with launched_here(RECIPES / "local_model_fallback.py", _ports(roboml=roboml), monkeypatch) as launcher:
        answers = _collect(launcher.transport, "llm_response", "String")
        assert _ask_brain(launcher.transport, answers)
    assert answers[0].strip(), answers  # the built-in local model answered


@pytest.mark.zenoh
def test_local_model_fallback_on_zenoh(roboml: RoboMLTestServer, tmp_path: Path) -> None:
    needs_smollm2()
    roboml.set_fault("error", times=1000)
    with launched_as_script(RECIPES / "local_model_fallback.py", _ports(roboml=roboml), tmp_path) as (proc, asker):
        answers = _collect(asker, "llm_response", "String")
        assert _ask_brain(asker, answers, proc)
    assert answers[0].strip(), answers


# -- event-driven visual description (multiprocessing=True upstream) ------------------------------------



def _ssd_ports(ollama: OllamaTestServer) -> dict[str, Any]:
    """The ports, and the shared COCO detector as the default local model (upstream's default is not offline)."""
    from ..components.vision_recipe import SSD_MODEL  # noqa: PLC0415

    return {**_ports(ollama), "AGENTS_VISION_MODEL": str(SSD_MODEL)}


def _person_photo() -> Any:
    from ..components.vision_recipe import needs_ssd, photo  # noqa: PLC0415  (needs Pillow and the model)

    needs_ssd()
    return photo("astronaut.png")


@pytest.mark.parametrize("recipe", [V060 / "event_driven_visual_description.py",
                                    V074 / "event_driven_visual_description.py"], ids=["0.6.0", "0.7.4"])
def test_event_driven_visual_description_in_one_process(recipe: Path, ollama: OllamaTestServer,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    picture = _person_photo()
    with launched_here(recipe, _ssd_ports(ollama), monkeypatch) as launcher:
        descriptions = _collect(launcher.transport, "/description", "String")
        assert ask_until(launcher.transport, Topic(name="/image_raw", msg_type="Image"), picture,
                         lambda: bool(descriptions), every=1.0)
    assert "say briefly what they look like" in descriptions[0]


@pytest.mark.zenoh
@pytest.mark.parametrize("recipe", [V060 / "event_driven_visual_description.py",
                                    V074 / "event_driven_visual_description.py"], ids=["0.6.0", "0.7.4"])
def test_event_driven_visual_description_on_zenoh(recipe: Path, ollama: OllamaTestServer, tmp_path: Path) -> None:
    picture = _person_photo()
    empty = np.zeros_like(picture)
    with launched_as_script(recipe, _ssd_ports(ollama), tmp_path) as (proc, asker):
        descriptions = _collect(asker, "/description", "String")
        # The event fires when a person *appears* (on_change). With the component processes forked
        # in ~0.2 s, it can fire before the describer's own camera subscription is routed, and the
        # question is then skipped ("no image has arrived yet"); an empty frame every few seconds
        # lets the person appear again, as a robot's camera would.
        shown = (empty if i % 7 == 6 else picture for i in itertools.count())
        pub = asker.create_publisher(Topic(name="/image_raw", msg_type="Image"))
        try:
            assert wait_for(lambda: bool(descriptions) or proc.proc.poll() is not None
                            or (pub.publish(next(shown)), False)[1], timeout=180, interval=1.0)
        finally:
            pub.close()
        assert descriptions
    assert "say briefly what they look like" in descriptions[0]


# -- recipes on a Chroma server --------------------------------------------------------------------------



@pytest.mark.parametrize("recipe", [V060 / "semantic_router.py", V074 / "semantic_router.py"], ids=["0.6.0", "0.7.4"])
def test_semantic_router(recipe: Path, ollama: OllamaTestServer, chroma_port: int,  # noqa: F811
                         monkeypatch: pytest.MonkeyPatch) -> None:
    # ChromaDB() embeds through Ollama where OLLAMA_HOST says (the stand-in), as Ollama's CLI reads it.
    monkeypatch.setenv("OLLAMA_HOST", f"127.0.0.1:{ollama.port}")
    with launched_here(recipe, _ports(ollama, chroma=chroma_port), monkeypatch) as launcher:
        t = launcher.transport
        chat = _collect(t, "text_out_llm", "String")
        t.create_publisher(Topic(name="question", msg_type="String")).publish("What is the capital of France?")
        assert wait_for(lambda: bool(chat), timeout=30)
    assert "What is the capital of France?" in chat[0]


def _fill_the_map_collection(port: int) -> None:
    from agents_core.clients import ChromaClient  # noqa: PLC0415
    from agents_core.vectordbs import ChromaDB  # noqa: PLC0415

    client = ChromaClient(ChromaDB(), port=port)
    client.initialize()
    try:
        client.add({"collection_name": "map", "ids": ["kitchen"], "documents": ["kitchen"],
                    "metadatas": [{"coordinates": "1.0, 2.0"}]})
    finally:
        client.deinitialize()


@pytest.mark.parametrize("name", ["go_to_x.py", "tool_calling.py"])
def test_go_to_x_and_tool_calling_0_6_0(name: str, chroma_port: int,  # noqa: F811
                                        monkeypatch: pytest.MonkeyPatch) -> None:
    reply = '{"position": "1.0, 2.0"}'
    tool_calls = [{"name": "get_coordinates", "arguments": {"position": [1.0, 2.0, 0.0]}}]
    with OllamaTestServer(models=OLLAMA_MODELS, reply=reply, tool_calls=tool_calls) as server:
        monkeypatch.setenv("OLLAMA_HOST", f"127.0.0.1:{server.port}")  # ChromaDB()'s embeddings
        _fill_the_map_collection(chroma_port)  # what upstream's semantic_map example leaves behind
        with launched_here(V060 / name, _ports(server, chroma=chroma_port), monkeypatch) as launcher:
            t = launcher.transport
            goals = _collect(t, "goal_point", "PoseStamped")
            t.create_publisher(Topic(name="goto_in", msg_type="String")).publish("Go to the kitchen")
            assert wait_for(lambda: bool(goals), timeout=30)
    assert list(goals[0].position) == [1.0, 2.0, 0.0]


def _map_entries(port: int, layer: str) -> list[str]:
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


def test_semantic_map_0_6_0(ollama: OllamaTestServer, roboml: RoboMLTestServer, chroma_port: int,  # noqa: F811
                            monkeypatch: pytest.MonkeyPatch) -> None:
    from agents_core.messages import Header, OccupancyGridMsg, OdometryMsg, PoseMsg  # noqa: PLC0415

    monkeypatch.setenv("UPSTREAM_TRIGGER", "2.0")  # a tick every 0.5 s instead of every 15 s
    monkeypatch.setenv("OLLAMA_HOST", f"127.0.0.1:{ollama.port}")  # ChromaDB()'s embeddings
    # The map arrives after the component started (upstream reads it at each step): no wait at configure.
    grid = OccupancyGridMsg(data=np.zeros((40, 40), np.int8), resolution=0.5,
                            origin=PoseMsg(position=[-10.0, -10.0, 0.0]), header=Header(frame_id="map"))
    with launched_here(V060 / "semantic_map.py", _ports(ollama, roboml, chroma_port), monkeypatch) as launcher:
        t = launcher.transport
        feeds = [(t.create_publisher(Topic(name=name, msg_type=kind)), value) for name, kind, value in (
            ("map", "OccupancyGrid", grid),
            ("odom", "Odometry", OdometryMsg(pose=PoseMsg(position=[1.0, 2.0, 0.0]), header=Header(frame_id="map"))),
            ("image_raw", "Image", _image()))]
        rooms = _collect(t, "introspection_answer", "String")

        def fed_and_mapped() -> bool:
            # Position, map and camera keep coming, as on a robot (a value needs a position younger than 2 s).
            for pub, value in feeds:
                pub.publish(value)
            return all(_map_entries(chroma_port, layer) for layer in ("detections", "introspection_answer"))

        assert wait_for(fed_and_mapped, timeout=60, interval=0.5)
    assert set(rooms) <= {"office", "bedroom", "kitchen"} and rooms, rooms  # the pre-processor kept one word
    assert _map_entries(chroma_port, "introspection_answer")[0] in {"office", "bedroom", "kitchen"}
