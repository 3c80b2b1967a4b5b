"""SpeechToText on the real Whisper tiny.en + Silero VAD (memory transport): clips streamed in 20 ms
chunks at 16 kHz and 48 kHz stereo, silence and noise, bad chunks, the bounded buffer, the wake word."""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core import Launcher, Topic
from agents_core.components import SpeechToText
from agents_core.config import SpeechToTextConfig
from agents_core.errors import ConfigError
from agents_core.messages import AudioMsg
from agents_core.status import HealthStatus

from ..conftest import wait_for
from .scripted_client import ScriptedChatClient
from .voice_recipe import as_48k_stereo, chunks, clip, needs_stt, needs_wakeword, silence

pytestmark = pytest.mark.local_models

MIC, HEARD = Topic("mic", "Audio"), Topic("heard", "String")


def _stt(**config: Any) -> SpeechToText:
    whisper, vad = needs_stt()
    cfg = SpeechToTextConfig(enable_local_model=True, local_model_path=whisper, vad_model_path=vad, **config)
    return SpeechToText(inputs=[MIC], outputs=[HEARD], config=cfg)


@contextmanager
def _running(stt: SpeechToText) -> Iterator[tuple[Any, list[str]]]:
    launcher = Launcher("memory")
    launcher.add_pkg(components=[stt])
    with launcher:
        heard: list[str] = []
        launcher.transport.create_subscription(HEARD, heard.append, inline=True)
        yield launcher.transport.create_publisher(MIC).publish, heard


def _settle(stt: SpeechToText) -> None:
    assert wait_for(lambda: not stt.busy, timeout=30), "the component did not finish the audio"


def test_each_utterance_of_a_clip_becomes_one_transcript_at_16k() -> None:
    stt = _stt()
    with _running(stt) as (publish, heard):
        for msg in chunks(np.concatenate([silence(0.3), clip("pick_up_red_cube_16k.wav"), silence(1.0)])):
            publish(msg)
        _settle(stt)
        assert len(heard) == 1, heard
        assert "red cube" in heard[0].lower()
        for msg in chunks(np.concatenate([clip("beckett_16k.wav"), silence(1.0)])):
            publish(msg)
        _settle(stt)
    assert "fail better" in " ".join(heard[1:]).lower(), heard
    assert stt.utterances == len(heard) and stt.dropped_chunks == 0 and stt.health_status == HealthStatus.HEALTHY


def test_48k_stereo_int16_and_float32_chunks_are_downmixed_and_resampled() -> None:
    stereo = as_48k_stereo(np.concatenate([silence(0.3), clip("pick_up_red_cube_16k.wav"), silence(1.0)]))
    stt = _stt()
    with _running(stt) as (publish, heard):
        for msg in chunks(stereo, rate=48_000, channels=2):
            publish(msg)
        _settle(stt)
        # Then float32 in 10 ms chunks (the first 2.5 s: enough for "please pick up the red cube").
        head = (stereo[: 48_000 * 2 * 5 // 2] / 32768.0).astype(np.float32)
        for msg in chunks(np.concatenate([head, np.zeros(48_000 * 2, np.float32)]), rate=48_000, channels=2, ms=10):
            publish(msg)
        _settle(stt)
    assert len(heard) == 2 and "red cube" in heard[0].lower() and "pick up" in heard[1].lower(), heard


def test_silence_and_noise_give_nothing() -> None:
    noise = (np.random.default_rng(3).normal(0, 0.02, 16_000 * 3) * 32767).astype(np.int16)
    stt = _stt()
    with _running(stt) as (publish, heard):
        for msg in chunks(np.concatenate([silence(2.0), noise, silence(1.0)])):
            publish(msg)
        _settle(stt)
    assert heard == [] and stt.health_status == HealthStatus.HEALTHY


def test_bad_chunks_set_the_health_and_the_next_good_audio_is_transcribed() -> None:
    stt = _stt()
    with _running(stt) as (publish, heard):
        publish(AudioMsg(data=np.zeros(0, np.int16)))  # empty: skipped
        publish(AudioMsg(data=np.array([0.1, np.nan, np.inf] * 100, np.float32)))
        _settle(stt)
        assert wait_for(lambda: stt.health_status == HealthStatus.ALGORITHM_FAILURE)
        publish(AudioMsg(data=np.zeros(320, np.int16), sample_rate=1))  # absurd rate
        publish(AudioMsg(data=np.zeros(16_000 * 600, np.int16)))  # one 10-minute chunk
        _settle(stt)
        assert stt.refused_chunks == 3 and heard == []
        for msg in chunks(np.concatenate([clip("pick_up_red_cube_16k.wav"), silence(1.0)])):
            publish(msg)
        _settle(stt)
        assert wait_for(lambda: stt.health_status == HealthStatus.HEALTHY)
    assert len(heard) == 1 and "red cube" in heard[0].lower()


def test_audio_arriving_during_inference_is_buffered_within_the_bound() -> None:
    stt = _stt(max_buffer_s=2.0)
    with _running(stt) as (publish, _heard):
        # Everything arrives at once (far faster than real time): only the newest 2 s are kept.
        for msg in chunks(np.concatenate([clip("beckett_16k.wav"), silence(1.0)])):
            publish(msg)
        _settle(stt)
    assert stt.dropped_chunks > 0 and stt.dropped_seconds <= 11.0
    assert stt.health_status == HealthStatus.HEALTHY


def test_wake_word_then_command_gives_the_command_and_the_command_alone_gives_nothing() -> None:
    needs_wakeword()
    # The espeak-ng wake clip peaks at ~0.95, a little under hey_jarvis's own (strict) cutoff of 0.97;
    # every other clip stays <= 0.02.
    stt = _stt(enable_wakeword=True, wakeword_model="hey_jarvis", wakeword_threshold=0.8)
    command = np.concatenate([clip("pick_up_red_cube_16k.wav"), silence(1.0)])
    with _running(stt) as (publish, heard):
        for msg in chunks(np.concatenate([silence(0.3), command])):
            publish(msg)
        _settle(stt)
        assert heard == [] and stt.ignored_utterances == 1
        for msg in chunks(np.concatenate([clip("wake_hey_jarvis_16k.wav"), silence(0.8), command])):
            publish(msg)
        _settle(stt)
    assert len(heard) == 1 and "red cube" in heard[0].lower(), heard
    assert "jarvis" not in heard[0].lower()


def test_config_checks() -> None:
    with pytest.raises(ConfigError, match="enable_vad"):
        SpeechToTextConfig(enable_wakeword=True, enable_vad=False)
    with pytest.raises(ConfigError):
        SpeechToTextConfig(wakeword_threshold=1.5)
    with pytest.raises(ConfigError):
        SpeechToTextConfig(vad_threshold=0.0)


def test_the_readme_voice_example_builds() -> None:
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    block = next(b for b in re.findall(r"```python\n(.*?)```", readme, flags=re.S) if "SpeechToText(" in b)
    namespace: dict[str, Any] = {}
    exec(compile(block, "README.md", "exec"), namespace)
    assert namespace["ears"].config.enable_wakeword and namespace["mouth"].config.stream


def test_a_remote_model_gets_each_utterance_as_16k_audio() -> None:
    _, vad = needs_stt()
    client = ScriptedChatClient([{"output": " pick up the red cube "}])
    stt = SpeechToText(inputs=[MIC], outputs=[HEARD], model_client=client,
                       config=SpeechToTextConfig(vad_model_path=vad))
    with _running(stt) as (publish, heard):
        for msg in chunks(as_48k_stereo(np.concatenate([clip("pick_up_red_cube_16k.wav"), silence(1.0)])),
                          rate=48_000, channels=2):
            publish(msg)
        _settle(stt)
    assert heard == ["pick up the red cube"]
    sent = client.inputs[0]
    assert sent["sample_rate"] == 16_000 and sent["query"].dtype == np.float32
    assert 3.5 < sent["query"].size / 16_000 < 5.5


def test_a_microphone_without_sounddevice_or_a_device_is_a_clear_configure_error() -> None:
    whisper, vad = needs_stt()
    stt = SpeechToText(outputs=[HEARD], config=SpeechToTextConfig(
        enable_local_model=True, local_model_path=whisper, vad_model_path=vad, enable_microphone=True,
        device_audio="no such microphone"))
    with pytest.raises(ConfigError, match=r"sounddevice|input device"):
        stt._check_microphone()
