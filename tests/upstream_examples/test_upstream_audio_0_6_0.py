"""Upstream 0.6.0's conversational_agent_with_audio.py, run unchanged on the memory transport.

The recipe differs from 0.7.4's in three ways, each exercised here: the text-to-speech model is
``SpeechT5`` (served by the RoboML stand-in as a ``TransformersTTS``), ``enable_vad=True`` cuts
the incoming audio into utterances with Silero VAD, and ``play_on_device=True`` plays the speech
instead of publishing it. Two stand-ins replace what the machine lacks, as the model servers are
replaced: a ``silero_vad`` package directory that ships the shared ``silero_vad.onnx`` (what
``pip install --no-deps silero-vad`` installs), and a ``sounddevice`` module with one output
device that records what it is asked to play (CI machines have no sound card).
"""

from __future__ import annotations

import sys
import threading
import types
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core.messages import AudioMsg
from agents_core.ros import Topic

from ..components.voice_recipe import VAD_FILE, clip, needs_stt, silence
from ..conftest import wait_for
from ..servers.ollama_server import OllamaTestServer
from ..servers.roboml_server import RoboMLTestServer
from .harness import RECIPES, launched_here

RECIPE = RECIPES / "v0_6_0" / "conversational_agent_with_audio.py"

pytestmark = pytest.mark.local_models


class FakeSoundDevice(types.ModuleType):
    """The part of ``sounddevice`` TextToSpeech's player uses, with one output device."""

    def __init__(self) -> None:
        super().__init__("sounddevice")
        self.played: list[tuple[np.ndarray, int]] = []
        self._lock = threading.Lock()

    def query_devices(self, device: Any = None, kind: str | None = None) -> dict[str, Any]:
        return {"name": "test speaker", "max_output_channels": 2}

    def play(self, samples: np.ndarray, rate: int, device: Any = None) -> None:
        with self._lock:
            self.played.append((np.asarray(samples), int(rate)))

    def wait(self) -> None:
        """Playback of the fake device ends at once."""

    def stop(self) -> None:
        """Nothing is playing."""


@pytest.fixture
def speaker(monkeypatch: pytest.MonkeyPatch) -> FakeSoundDevice:
    device = FakeSoundDevice()
    monkeypatch.setitem(sys.modules, "sounddevice", device)
    return device


@pytest.fixture
def silero_vad_package(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """What ``pip install --no-deps silero-vad`` puts on the path: a package with data/silero_vad.onnx."""
    needs_stt()
    package = tmp_path / "site" / "silero_vad"
    (package / "data").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "data" / "silero_vad.onnx").symlink_to(VAD_FILE)
    monkeypatch.syspath_prepend(str(tmp_path / "site"))


@pytest.fixture
def servers() -> Iterator[tuple[OllamaTestServer, RoboMLTestServer]]:
    with OllamaTestServer(models=["qwen2.5vl:latest"]) as ollama, RoboMLTestServer() as roboml:
        yield ollama, roboml


def _image() -> np.ndarray:
    return np.random.default_rng(7).integers(0, 255, size=(48, 64, 3), dtype=np.uint8)


@pytest.mark.usefixtures("silero_vad_package")
def test_conversational_agent_with_audio_0_6_0(servers: tuple[OllamaTestServer, RoboMLTestServer],
                                               speaker: FakeSoundDevice, monkeypatch: pytest.MonkeyPatch) -> None:
    ollama, roboml = servers
    ports = {"UPSTREAM_OLLAMA_PORT": ollama.port, "UPSTREAM_ROBOML_PORT": roboml.port,
             "UPSTREAM_ROBOML_RESP_PORT": roboml.resp_port}
    with launched_here(RECIPE, ports, monkeypatch) as launcher:
        t = launcher.transport
        transcripts: list[str] = []
        replies: list[str] = []
        t.create_subscription(Topic(name="text0", msg_type="String"), transcripts.append)
        t.create_subscription(Topic(name="text1", msg_type="String"), replies.append)
        t.create_publisher(Topic(name="image_raw", msg_type="Image")).publish(_image())
        # One utterance between silences: VAD cuts it out and only it reaches Whisper.
        speech = np.concatenate([silence(0.5), clip("pick_up_red_cube_16k.wav"), silence(1.0)])
        t.create_publisher(Topic(name="audio0", msg_type="Audio")).publish(
            AudioMsg(data=speech, sample_rate=16000))
        assert wait_for(lambda: bool(replies), timeout=30), (transcripts, replies)
        assert wait_for(lambda: bool(speaker.played), timeout=30), "nothing was played on the device"
    # The stand-in Whisper says how many samples it got: the utterance, not the silence around it.
    heard = int(transcripts[0].split()[1])
    assert 0 < heard < speech.size, (heard, speech.size)
    assert "".join(replies).startswith("You said: " + transcripts[0][:10]), (transcripts, replies)
    samples, rate = speaker.played[0]
    assert rate > 0 and samples.size > 0
    # The speech came from a TransformersTTS node loaded with SpeechT5's checkpoint and voice.
    added = [c.payload for c in roboml.calls_of("add_node") if c.node == "speecht5"]
    init = [c.payload for c in roboml.calls_of("initialize") if c.node == "speecht5"]
    assert added and "TransformersTTS" in str(added[0]), added
    assert init and init[0]["checkpoint"] == "microsoft/speecht5_tts" and init[0]["voice"] == "clb", init
