"""``examples/voice_loop.py`` on memory: a spoken question from ../shared/audio comes back as spoken audio.

The example runs as a user runs it (``--wav CLIP --out ANSWER.wav --once``). The test checks the
transcript, and that the answer's audio says the answer: Whisper transcribes the written WAV back
and most of the answer's words must be in it (a silent, cut or garbled answer fails).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from tests.components.voice_recipe import SHARED_AUDIO, VAD_FILE, WHISPER_DIR, needs_voice_loop

from .test_examples import _run_example

pytestmark = [pytest.mark.local_models, pytest.mark.slow]


def _words(text: str) -> list[str]:
    return re.findall(r"[a-z']+", text.lower())


def _transcribe(wav: Path) -> str:
    import sherpa_onnx  # noqa: PLC0415  (the local extra; needs_voice_loop checked it)

    from agents_core.engines.audio import read_wav  # noqa: PLC0415

    recognizer = sherpa_onnx.OfflineRecognizer.from_whisper(
        encoder=str(WHISPER_DIR / "tiny.en-encoder.int8.onnx"), decoder=str(WHISPER_DIR / "tiny.en-decoder.int8.onnx"),
        tokens=str(WHISPER_DIR / "tiny.en-tokens.txt"), language="en", task="transcribe")
    samples, rate, channels = read_wav(wav)
    assert channels == 1
    stream = recognizer.create_stream()
    stream.accept_waveform(rate, samples.astype(np.float32) / 32768.0)
    recognizer.decode_stream(stream)
    return str(stream.result.text)


def test_voice_loop_answers_a_spoken_question_with_speech(tmp_path: Path) -> None:
    needs_voice_loop()
    out = tmp_path / "answer.wav"
    stdout = _run_example("voice_loop.py", "--wav", str(SHARED_AUDIO / "pick_up_red_cube_16k.wav"),
                          "--out", str(out), "--stt-model", str(WHISPER_DIR), "--vad-model", str(VAD_FILE),
                          "--once", "--seconds", "240", timeout=300)
    lines = stdout.splitlines()
    heard = [line for line in lines if line.startswith("heard: ")]
    answers = [line[len("answer: "):] for line in lines if line.startswith("answer: ")]
    spoken = [line for line in lines if line.startswith("spoken: ")]
    assert len(heard) == 1 and "red cube" in heard[0].lower(), stdout
    assert len(answers) == 1 and _words(answers[0]), stdout
    assert len(spoken) == 1 and spoken[0].endswith("at 22050 Hz"), stdout
    assert out.is_file()
    said = _words(_transcribe(out))
    meant = _words(answers[0])
    # Whisper tiny may mishear a word or two of a synthetic voice, not most of them.
    assert sum(word in said for word in meant) >= 0.6 * len(meant), (answers[0], said)
