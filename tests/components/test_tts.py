"""TextToSpeech on the real Piper voice (sherpa-onnx VITS): streamed sentences, the round trip through
SpeechToText, actions, limits and wiring errors (memory transport)."""

from __future__ import annotations

import difflib
import re
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import pytest

from agents_core import Launcher, Topic
from agents_core.components import SpeechToText, TextToSpeech
from agents_core.config import SpeechToTextConfig, TextToSpeechConfig
from agents_core.engines.audio import wav_bytes
from agents_core.engines.local_stt import LocalSTT
from agents_core.engines.local_tts import LocalTTS, split_sentences
from agents_core.errors import ConfigError, WiringError
from agents_core.messages import AudioMsg, StreamingStringMsg
from agents_core.status import HealthStatus

from ..conftest import wait_for
from .scripted_client import ScriptedChatClient
from .voice_recipe import needs_stt, voice_dir

pytestmark = pytest.mark.local_models

TEXT, STREAM, SPOKEN = Topic("text", "String"), Topic("answer", "StreamingString"), Topic("spoken", "Audio")
HEARD = Topic("heard", "String")


def _tts(**config: Any) -> TextToSpeech:
    cfg = TextToSpeechConfig(enable_local_model=True, local_model_path=str(voice_dir()), **config)
    return TextToSpeech(inputs=[TEXT, STREAM], outputs=[SPOKEN], config=cfg)


@contextmanager
def _running(*components: Any) -> Iterator[tuple[Launcher, list[AudioMsg]]]:
    launcher = Launcher("memory")
    launcher.add_pkg(components=list(components))
    with launcher:
        audio: list[AudioMsg] = []
        launcher.transport.create_subscription(SPOKEN, audio.append, inline=True)
        yield launcher, audio


def test_split_sentences_keeps_the_unfinished_rest() -> None:
    assert split_sentences("Hello there. How are you? I am 3.5 m") == (["Hello there.", "How are you?"], "I am 3.5 m")
    assert split_sentences("one\ntwo") == (["one"], "two")
    assert split_sentences("") == ([], "")


def test_round_trip_text_to_speech_to_text() -> None:
    whisper, vad = needs_stt()
    tts = _tts()
    stt = SpeechToText(inputs=[SPOKEN], outputs=[HEARD], config=SpeechToTextConfig(
        enable_local_model=True, local_model_path=whisper, vad_model_path=vad))
    with _running(tts, stt) as (launcher, audio):
        heard: list[str] = []
        launcher.transport.create_subscription(HEARD, heard.append, inline=True)
        launcher.transport.create_publisher(TEXT).publish("Please pick up the red cube.")
        assert wait_for(lambda: not tts.busy and audio, timeout=30)
        # Trailing silence ends the utterance for the VAD, as a pause would.
        launcher.transport.create_publisher(SPOKEN).publish(AudioMsg(data=np.zeros(22_050, np.int16),
                                                                     sample_rate=22_050))
        assert wait_for(lambda: heard, timeout=30), "nothing heard"
    assert all(a.sample_rate == 22_050 and a.data.dtype == np.int16 for a in audio)
    assert 1.0 < sum(a.duration for a in audio) < 5.0
    assert "red cube" in heard[0].lower(), heard


def test_a_stream_is_spoken_sentence_by_sentence_before_it_ends() -> None:
    tts = _tts(chunk_ms=50)
    with _running(tts) as (launcher, audio):
        publish = launcher.transport.create_publisher(STREAM).publish
        for word in ["The", "red", "cube", "is", "on", "the", "table.", ""]:
            publish(StreamingStringMsg(data=word + " ", stream=True, done=False))
        assert wait_for(lambda: audio, timeout=20), "the first sentence was not spoken before the stream ended"
        assert tts.sentences_spoken == 1
        publish(StreamingStringMsg(data="I will pick it up", stream=True, done=False))
        time.sleep(0.3)
        assert tts.sentences_spoken == 1  # unfinished: waits for more
        publish(StreamingStringMsg(data="", stream=True, done=True))
        assert wait_for(lambda: tts.sentences_spoken == 2 and not tts.busy, timeout=20)
    assert all(a.duration <= 0.05 + 1e-6 for a in audio)


def _words(text: str) -> list[str]:
    return re.findall(r"[a-z0-9']+", text.lower())


def test_the_first_clause_is_spoken_first_and_the_whole_answer_is_heard_once() -> None:
    whisper, _ = needs_stt()
    answer = ("The red cube is on the table, next to the window. I will drive there and pick it up now. "
              "Tell me where you want me to put it.")
    tts = _tts(chunk_ms=50)
    with _running(tts) as (launcher, audio):
        publish = launcher.transport.create_publisher(STREAM).publish
        for word in answer.split(" "):
            publish(StreamingStringMsg(data=word + " ", stream=True, done=False))
        publish(StreamingStringMsg(data="", stream=True, done=True))
        assert wait_for(lambda: tts.sentences_spoken == 4 and not tts.busy, timeout=60)
    assert tts.dropped_sentences == 0
    assert {a.sample_rate for a in audio} == {22_050}
    spoken = np.concatenate([a.data for a in audio]).astype(np.float32) / 32768.0
    # The pieces together last about as long as the answer synthesized whole (nothing dropped or repeated).
    whole = LocalTTS(str(voice_dir())).synthesize(answer)
    assert 0.85 < spoken.size / whole.size < 1.2, (spoken.size, whole.size)
    heard = _words(LocalSTT(whisper).transcribe(spoken, 22_050))
    expected = _words(answer)
    assert difflib.SequenceMatcher(a=expected, b=heard).ratio() >= 0.9, heard
    assert heard.count("table") == 1 and heard.count("window") == 1, heard


def test_say_stop_playback_limits_and_recovery() -> None:
    tts = _tts(max_text_chars=2000)
    with _running(tts) as (launcher, audio):
        launcher.transport.create_publisher(TEXT).publish("x" * 100_000)
        assert wait_for(lambda: tts.health_status == HealthStatus.ALGORITHM_FAILURE)
        assert tts.refused_texts == 1 and audio == []
        assert tts.say("One. Two. Three. Four. Five. Six.")
        assert wait_for(lambda: tts.sentences_spoken >= 1, timeout=20)
        assert tts.stop_playback()
        assert wait_for(lambda: not tts.busy, timeout=20)
        assert tts.sentences_spoken <= 3 and tts.dropped_sentences >= 3
        assert tts.say("Hello.")
        assert wait_for(lambda: tts.health_status == HealthStatus.HEALTHY, timeout=20)
    assert audio


def test_wiring_and_missing_device_errors() -> None:
    with pytest.raises(WiringError, match="play_on_device"):
        TextToSpeech(inputs=[TEXT], outputs=[], config=TextToSpeechConfig(enable_local_model=True))
    tts = TextToSpeech(inputs=[TEXT], outputs=[SPOKEN], config=TextToSpeechConfig(
        enable_local_model=True, local_model_path=str(voice_dir()), play_on_device=True, device="no such device"))
    with pytest.raises(ConfigError, match=r"sounddevice|device"):
        tts.custom_on_configure()


def test_a_remote_voice_answering_wav_is_decoded_and_published() -> None:
    tone = (0.3 * np.sin(np.arange(16_000) / 16_000 * 2 * np.pi * 220) * 32767).astype(np.int16)
    client = ScriptedChatClient([{"output": wav_bytes(tone, 16_000)}])
    tts = TextToSpeech(inputs=[TEXT], outputs=[SPOKEN], model_client=client, config=TextToSpeechConfig(chunk_ms=100))
    with _running(tts) as (launcher, audio):
        launcher.transport.create_publisher(TEXT).publish("Hello there. How are you?")
        assert wait_for(lambda: tts.sentences_spoken == 2 and not tts.busy, timeout=10)
    assert [i["query"] for i in client.inputs] == ["Hello there.", "How are you?"]
    assert len(audio) == 20 and all(a.sample_rate == 16_000 for a in audio)
