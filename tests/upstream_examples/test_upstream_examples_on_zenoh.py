"""Upstream's recipes that run in one process here, run again on Zenoh with ``multiprocessing=True``.

Issue 26 asks every upstream example (0.6.0 and 0.7.4, Memory/Cortex aside) to run unchanged in one
process on memory *and* with one process per component on Zenoh. The recipes below leave
``multiprocessing`` off, as upstream's do; :func:`~.harness.launched_in_processes` runs each file as
a script with every ``add_pkg()`` given ``multiprocessing=True`` (``AGENTS_MULTIPROCESSING=1``),
feeds the inputs :mod:`.test_upstream_examples` feeds, from a Zenoh asker, and checks the same
outputs. Each test starts several processes: the timeouts are hang guards, not speed checks.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core.messages import AudioMsg
from agents_core.ros import Topic

from ..clients.test_chroma_client import chroma_port  # noqa: F401  (a fixture, used by name)
from ..conftest import wait_for
from ..servers.ollama_server import OllamaTestServer
from ..servers.roboml_server import RoboMLTestServer
from .harness import ask_until, launched_in_processes
from .test_upstream_examples import (
    OLLAMA_MODELS,
    V060,
    V074,
    _collect,
    _fill_the_map_collection,
    _image,
    _map_entries,
    _ports,
)

pytestmark = [pytest.mark.zenoh, pytest.mark.slow]

@pytest.fixture
def ollama() -> Iterator[OllamaTestServer]:
    server = OllamaTestServer(models=OLLAMA_MODELS)
    with server:
        yield server


@pytest.fixture
def roboml() -> Iterator[RoboMLTestServer]:
    with RoboMLTestServer() as server:
        yield server


#: The bound of every wait below: component processes start slowly on a loaded machine.
HANG_GUARD = 180.0


def _in_own_processes(proc: Any, *names: str) -> bool:
    """Each component named logged from a process of its own (``[name PID]``), not the recipe's."""
    log = proc.log_path.read_text(errors="replace")
    found = {m.group(1): int(m.group(2)) for m in re.finditer(r"^\[(\S+) (\d+)\] ", log, re.MULTILINE)}
    return all(name in found and found[name] != proc.pid for name in names)


def _feed(asker: Any, proc: Any, topic: Topic, value: Any, got: list[Any]) -> bool:
    """Publish ``value`` until something arrives in ``got`` (or the recipe process has exited)."""
    return ask_until(asker, topic, value, lambda: bool(got) or proc.proc.poll() is not None,
                     timeout=HANG_GUARD, every=2.0) and bool(got)


@pytest.mark.parametrize("recipe", [V060 / "prompt_engineering.py", V074 / "prompt_engineering.py"],
                         ids=["0.6.0", "0.7.4"])
def test_prompt_engineering_in_processes(recipe: Path, ollama: OllamaTestServer, roboml: RoboMLTestServer,
                                         tmp_path: Path) -> None:
    with launched_in_processes(recipe, _ports(ollama, roboml), tmp_path) as (proc, asker):
        detections, answers = _collect(asker, "detections", "Detections"), _collect(asker, "text1", "String")
        assert _feed(asker, proc, Topic(name="image_raw", msg_type="Image"), _image(), detections)
        assert _feed(asker, proc, Topic(name="text0", msg_type="String"), "What is on the table?", answers)
    assert _in_own_processes(proc, "detection_component", "mllm_component")
    assert "Items detected in it: object." in answers[0]
    assert "Question about it: What is on the table?" in answers[0]


def test_conversational_agent_with_audio_0_7_4_in_processes(ollama: OllamaTestServer, roboml: RoboMLTestServer,
                                                           tmp_path: Path) -> None:
    recipe = V074 / "conversational_agent_with_audio.py"
    with launched_in_processes(recipe, _ports(ollama, roboml), tmp_path) as (proc, asker):
        transcripts, replies = _collect(asker, "text0", "String"), _collect(asker, "text1", "String")
        spoken = _collect(asker, "audio_out", "Audio")
        camera, microphone = asker.create_publisher(Topic(name="image_raw", msg_type="Image")), \
            asker.create_publisher(Topic(name="audio0", msg_type="Audio"))
        audio = AudioMsg(data=np.zeros(16000, dtype=np.int16), sample_rate=16000)

        def speak() -> bool:  # a frame and the speech, again until the reply (discovery can drop the first ones)
            if replies or proc.proc.poll() is not None:
                return True
            camera.publish(_image())
            microphone.publish(audio)
            return False

        assert wait_for(speak, timeout=HANG_GUARD, interval=2.0) and replies, (transcripts, replies)
        assert wait_for(lambda: bool(spoken) or proc.proc.poll() is not None, timeout=HANG_GUARD) and spoken
    assert _in_own_processes(proc, "speech_to_text", "vqa", "text_to_speech")
    # The speech may be heard as more than one utterance; the reply echoes one of them.
    assert transcripts and any("".join(replies).startswith("You said: " + t[:10]) for t in transcripts), \
        (transcripts, replies)


@pytest.mark.parametrize("recipe", [V060 / "semantic_router.py", V074 / "semantic_router.py"], ids=["0.6.0", "0.7.4"])
def test_semantic_router_in_processes(recipe: Path, ollama: OllamaTestServer, chroma_port: int,  # noqa: F811
                                      tmp_path: Path) -> None:
    # ChromaDB() embeds through Ollama where OLLAMA_HOST says (the stand-in), in every component process.
    with launched_in_processes(recipe, _ports(ollama, chroma=chroma_port), tmp_path,
                               env={"OLLAMA_HOST": f"127.0.0.1:{ollama.port}"}) as (proc, asker):
        chat = _collect(asker, "text_out_llm", "String")
        assert _feed(asker, proc, Topic(name="question", msg_type="String"), "What is the capital of France?", chat)
    assert _in_own_processes(proc, "generic_llm", "go_to_x", "router")
    assert "What is the capital of France?" in chat[0]


@pytest.mark.parametrize("name", ["go_to_x.py", "tool_calling.py"])
def test_go_to_x_and_tool_calling_0_6_0_in_processes(name: str, chroma_port: int,  # noqa: F811
                                                     tmp_path: Path) -> None:
    reply = '{"position": "1.0, 2.0"}'
    tool_calls = [{"name": "get_coordinates", "arguments": {"position": [1.0, 2.0, 0.0]}}]
    server = OllamaTestServer(models=OLLAMA_MODELS, reply=reply, tool_calls=tool_calls)
    with server:
        host = {"OLLAMA_HOST": f"127.0.0.1:{server.port}"}  # ChromaDB()'s embeddings
        with pytest.MonkeyPatch.context() as mp:  # the collection is filled from this process
            mp.setenv("OLLAMA_HOST", host["OLLAMA_HOST"])
            _fill_the_map_collection(chroma_port)
        with launched_in_processes(V060 / name, _ports(server, chroma=chroma_port), tmp_path,
                                   env=host) as (proc, asker):
            goals = _collect(asker, "goal_point", "PoseStamped")
            assert _feed(asker, proc, Topic(name="goto_in", msg_type="String"), "Go to the kitchen", goals)
    assert _in_own_processes(proc, "go_to_x")
    assert list(goals[0].position) == [1.0, 2.0, 0.0]


def test_semantic_map_0_6_0_in_processes(ollama: OllamaTestServer, roboml: RoboMLTestServer,
                                         chroma_port: int, tmp_path: Path) -> None:  # noqa: F811
    from agents_core.messages import Header, OccupancyGridMsg, OdometryMsg, PoseMsg  # noqa: PLC0415

    grid = OccupancyGridMsg(data=np.zeros((40, 40), np.int8), resolution=0.5,
                            origin=PoseMsg(position=[-10.0, -10.0, 0.0]), header=Header(frame_id="map"))
    odom = OdometryMsg(pose=PoseMsg(position=[1.0, 2.0, 0.0]), header=Header(frame_id="map"))
    # A tick every 0.5 s instead of every 15 s; ChromaDB() embeds through the stand-in in every process.
    env = {"UPSTREAM_TRIGGER": "2.0", "OLLAMA_HOST": f"127.0.0.1:{ollama.port}"}
    with launched_in_processes(V060 / "semantic_map.py", _ports(ollama, roboml, chroma_port), tmp_path,
                               env=env) as (proc, asker):
        feeds = [(asker.create_publisher(Topic(name=name, msg_type=kind)), value) for name, kind, value in (
            ("map", "OccupancyGrid", grid), ("odom", "Odometry", odom), ("image_raw", "Image", _image()))]

        def fed_and_mapped() -> bool:
            # Position, map and camera keep coming, as on a robot (a value needs a recent position).
            if proc.proc.poll() is not None:
                return True
            for pub, value in feeds:
                pub.publish(value)
            return all(_map_entries(chroma_port, layer) for layer in ("detections", "introspection_answer"))

        assert wait_for(fed_and_mapped, timeout=HANG_GUARD, interval=0.5) and proc.proc.poll() is None
    assert _in_own_processes(proc, "map_encoding")
    assert _map_entries(chroma_port, "introspection_answer")[0] in {"office", "bedroom", "kitchen"}


def test_conversational_agent_with_audio_0_6_0_in_processes(ollama: OllamaTestServer, roboml: RoboMLTestServer,
                                                           tmp_path: Path) -> None:
    import os  # noqa: PLC0415

    from ..components.voice_recipe import VAD_FILE, clip, needs_stt, silence  # noqa: PLC0415

    needs_stt()
    # What `pip install --no-deps silero-vad` puts on the path, and a sound card (play_on_device=True),
    # first on every component process's path.
    package = tmp_path / "site" / "silero_vad"
    (package / "data").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "data" / "silero_vad.onnx").symlink_to(VAD_FILE)
    standin = Path(__file__).resolve().parent / "sound_device_standin"
    path = os.pathsep.join([str(tmp_path / "site"), str(standin)])
    ports = {"UPSTREAM_OLLAMA_PORT": ollama.port, "UPSTREAM_ROBOML_PORT": roboml.port,
             "UPSTREAM_ROBOML_RESP_PORT": roboml.resp_port}
    speech = np.concatenate([silence(0.5), clip("pick_up_red_cube_16k.wav"), silence(1.0)])
    with launched_in_processes(V060 / "conversational_agent_with_audio.py", ports, tmp_path,
                               env={"PYTHONPATH": path}) as (proc, asker):
        transcripts, replies = _collect(asker, "text0", "String"), _collect(asker, "text1", "String")
        camera = asker.create_publisher(Topic(name="image_raw", msg_type="Image"))
        microphone = asker.create_publisher(Topic(name="audio0", msg_type="Audio"))

        def speak() -> bool:  # a frame and the utterance, again until the reply (discovery can drop the first)
            if replies or proc.proc.poll() is not None:
                return True
            camera.publish(_image())
            microphone.publish(AudioMsg(data=speech, sample_rate=16000))
            return False

        assert wait_for(speak, timeout=HANG_GUARD, interval=3.0) and replies, (transcripts, replies)
    # The speech may be heard as more than one utterance; the reply echoes one of them.
    assert transcripts and any("".join(replies).startswith("You said: " + t[:10]) for t in transcripts), \
        (transcripts, replies)
    added = [c.payload for c in roboml.calls_of("add_node") if c.node == "speecht5"]
    assert added and "TransformersTTS" in str(added[0]), added  # SpeechT5 loaded in the TTS component's process
