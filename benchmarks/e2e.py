"""End-to-end loops: a whole recipe against the sum of its stages run directly, in the same child.

Two loops, each on the memory and the Zenoh transport (one process; Zenoh: a peer session on
127.0.0.1, multicast scouting off), with the same local models on both sides:

- ``voice_loop``: the speech file (``pick_up_red_cube_16k.wav`` and 1 s of silence, one utterance)
  -> SpeechToText (Whisper tiny.en int8, Silero VAD) -> String -> LLM (SmolLM2 on llama.cpp,
  streamed, ``temperature=0``) -> StreamingString -> TextToSpeech (Piper "joe") -> the first Audio
  chunk. framework: the speech published as 20 ms Audio chunks as fast as possible; the clock runs
  from the first chunk to the first Audio message at a subscriber. raw (the stage sum): the same
  engines called directly, one after another: ``SpeechSegmenter`` + ``LocalSTT`` on the same chunks
  until the utterance's text (one segmenter for all repetitions, fed the trailing silence untimed,
  as the component's, so both hear the same utterance); ``LocalLLM`` streaming the same message until
  :func:`~agents_core.engines.local_tts.split_speakable` has a first piece; ``LocalTTS`` speaking
  it. In the recipe the LLM goes on generating while TTS speaks its first piece (the same 2
  cores), so part of the difference is that contention, not the framework.
- ``perception_loop``: a 640x480 photo -> Vision (the COCO SSD MobileNetV2 of ``../shared/models``)
  -> Detections -> MLLM (the tiny random VLM of ``../shared/models/tiny-random`` on llama.cpp,
  triggered by the Detections, which preface its question) -> the String answer. framework: from
  publishing the Image to the answer at a subscriber. raw: ``LocalVisionModel.detect`` then
  ``LocalVLM`` on the same prompt and image.

Raw and framework alternate, after one untimed run of each. framework / raw - 1 is the
framework's overhead (target <= 10 %). ``python -m benchmarks.e2e --loop voice|perception --reps N``
is the child; :func:`run_suite` runs both.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

from . import model as model_suite
from . import vision as vision_suite
from . import voice as voice_suite
from .common import ChildFailed, Children, available, child_env, emit, log, zenoh_framework_options

QUESTION = "What is in front of the robot? Answer in a few words."
LOOP_TIMEOUT = 120.0
TINY_VLM = vision_suite.SHARED_MODELS / "tiny-random"


def unavailable_reason(loop: str) -> str | None:
    """Why ``loop`` cannot run here, or None."""
    if not (available("zenoh") and available("msgpack")):
        return "the zenoh extra is not installed (pip install 'agents-core[zenoh]')"
    if loop == "voice":
        return voice_suite.unavailable_reason() or voice_suite.tts_unavailable_reason() or \
            model_suite.unavailable_reason()
    reason = vision_suite.unavailable_reason() or model_suite.unavailable_reason()
    if reason is None and not (TINY_VLM / "tiny-mmproj.gguf").is_file():
        reason = f"the tiny random VLM is not in {TINY_VLM} (set AGENTS_SHARED_MODELS)"
    return reason


def _launcher(transport: str, components: list[Any]) -> Any:
    from agents_core import Launcher  # noqa: PLC0415

    options = zenoh_framework_options(["tcp/127.0.0.1:0"], [], f"e2e_{os.getpid()}") if transport == "zenoh" else {}
    launcher = Launcher(transport=transport, transport_options=options)
    launcher.add_pkg(components=components)
    return launcher


def _wait(condition: Callable[[], bool], what: str) -> None:
    deadline = time.monotonic() + LOOP_TIMEOUT
    while not condition():
        if time.monotonic() > deadline:
            raise RuntimeError(f"timed out waiting for {what}")
        time.sleep(0.002)


# -- the voice loop -------------------------------------------------------------------------------


class VoiceLoop:
    """The voice loop's engines (raw) and recipe (framework) with the same settings."""

    def __init__(self, max_tokens: int) -> None:
        import numpy as np  # noqa: PLC0415

        from agents_core.config import LLMConfig, SpeechToTextConfig, TextToSpeechConfig  # noqa: PLC0415
        from agents_core.engines.audio import read_wav  # noqa: PLC0415

        clip = read_wav(voice_suite.AUDIO / "pick_up_red_cube_16k.wav")[0]
        self.pcm = np.concatenate([clip, np.zeros(16_000, np.int16)])
        self.voice = voice_suite._voice_dir()
        self.stt_config = SpeechToTextConfig(
            enable_local_model=True, local_model_path=str(voice_suite.WHISPER), vad_model_path=str(voice_suite.VAD),
            ncpu_local_model=voice_suite.THREADS, warmup=True, log_level="warning")
        self.llm_config = LLMConfig(enable_local_model=True, stream=True, temperature=0.0, max_new_tokens=max_tokens,
                                    ncpu_local_model=1, local_model_path=str(model_suite.model_path()),
                                    warmup=True, log_level="warning")
        self.tts_config = TextToSpeechConfig(enable_local_model=True, local_model_path=str(self.voice),
                                             ncpu_local_model=voice_suite.THREADS, warmup=True, log_level="warning")

    def raw(self) -> dict[str, Any]:
        import numpy as np  # noqa: PLC0415

        from agents_core.engines.audio import to_mono_float  # noqa: PLC0415
        from agents_core.engines.local_llm import LocalLLM  # noqa: PLC0415
        from agents_core.engines.local_stt import LocalSTT, SpeechSegmenter  # noqa: PLC0415
        from agents_core.engines.local_tts import LocalTTS, split_speakable  # noqa: PLC0415

        s = self.stt_config
        if not hasattr(self, "_engines"):
            l_, t = self.llm_config, self.tts_config
            stt = LocalSTT(str(s.local_model_path), ncpu=s.ncpu_local_model)
            stt.transcribe(np.zeros(8_000, np.float32))  # warm-up, as the components'
            llm = LocalLLM(str(l_.local_model_path), ncpu=l_.ncpu_local_model)
            tts = LocalTTS(str(t.local_model_path), ncpu=t.ncpu_local_model)
            tts.synthesize("Ready.")
            # One stream for all repetitions, as the component's: the detector's state carries over.
            segmenter = SpeechSegmenter(s.vad_model_path, threshold=s.vad_threshold,
                                        min_silence_ms=s.min_silence_duration_ms,
                                        min_speech_ms=s.min_speech_duration_ms, max_speech_s=s.max_speech_duration_s)
            self._engines = (stt, llm, tts, segmenter)
        stt, llm, tts, segmenter = self._engines
        l_ = self.llm_config
        chunks = [to_mono_float(self.pcm[i:i + 320]) for i in range(0, self.pcm.size, 320)]
        start = time.perf_counter()
        text, fed = "", len(chunks)
        for i, chunk in enumerate(chunks):
            done = segmenter.accept(chunk)
            if done:
                text, fed = stt.transcribe(done[0][1]), i + 1
                break
        heard = time.perf_counter()
        stream = llm({"query": [{"role": "user", "content": text}], "stream": True, "temperature": 0.0,
                      "max_new_tokens": l_.max_new_tokens})["output"]
        answer, pieces = "", []
        for chunk in stream:
            answer += chunk
            pieces, _ = split_speakable(answer, first=True, min_clause_words=self.tts_config.first_clause_words)
            if pieces:
                break
        piece = pieces[0] if pieces else answer.strip()
        answered = time.perf_counter()
        tts.synthesize(piece)
        spoken = time.perf_counter()
        for _ in stream:  # the rest of the answer is no stage of the first audio: drained, untimed
            pass
        for chunk in chunks[fed:]:  # and the silence after the utterance, which the component also hears
            segmenter.accept(chunk)
        return {"loop_ms": (spoken - start) * 1000, "stt_ms": (heard - start) * 1000,
                "llm_ms": (answered - heard) * 1000, "tts_ms": (spoken - answered) * 1000, "heard": text,
                "first_piece": piece}

    def framework(self, transport: str, reps: int, record: Callable[[dict[str, Any]], None],
                  raw: Callable[[], dict[str, Any]]) -> None:
        from agents_core import Topic  # noqa: PLC0415
        from agents_core.components import LLM, SpeechToText, TextToSpeech  # noqa: PLC0415
        from agents_core.messages import AudioMsg  # noqa: PLC0415

        mic, heard, answer = Topic("e2e/mic", "Audio"), Topic("e2e/heard", "String"), Topic("e2e/answer",
                                                                                          "StreamingString")
        spoken = Topic("e2e/spoken", "Audio")
        stt = SpeechToText(inputs=[mic], outputs=[heard], config=self.stt_config, component_name="e2e_ears")
        llm = LLM(inputs=[heard], outputs=[answer], config=self.llm_config, trigger=heard, component_name="e2e_brain")
        tts = TextToSpeech(inputs=[answer], outputs=[spoken], config=self.tts_config, component_name="e2e_mouth")
        chunks = [AudioMsg(data=self.pcm[i:i + 320]) for i in range(0, self.pcm.size, 320)]
        first_at: list[float] = []
        texts: list[str] = []
        said: list[str] = []
        ended = threading.Event()

        def on_audio(msg: Any) -> None:
            if not first_at:
                first_at.append(time.perf_counter())

        def on_answer(msg: Any) -> None:
            said.append(msg.data)
            if msg.done:
                ended.set()

        launcher = _launcher(transport, [stt, llm, tts])
        with launcher:
            t = launcher.transport
            t.create_subscription(spoken, on_audio, inline=True)
            t.create_subscription(heard, texts.append, inline=True)
            t.create_subscription(answer, on_answer, inline=True)
            publish = t.create_publisher(mic).publish
            time.sleep(0.5)  # Zenoh: the subscriptions reach the publishers
            for rep in range(reps + 1):  # rep 0: warm-up, not recorded
                raw_run = raw()
                first_at.clear()
                said.clear()
                ended.clear()
                start = time.perf_counter()
                for msg in chunks:
                    publish(msg)
                _wait(lambda: bool(first_at), "the first audio chunk")
                took = (first_at[0] - start) * 1000
                _wait(lambda: ended.is_set() and not tts.busy and not stt.busy, "the end of the answer")
                if rep:
                    record({**raw_run, "mode": "raw", "rep": rep})
                    record({"mode": "framework", "loop_ms": took, "heard": texts[-1] if texts else "",
                            "answer_head": "".join(said)[:60], "rep": rep})


# -- the perception loop --------------------------------------------------------------------------


class PerceptionLoop:
    """The perception loop's engines (raw) and recipe (framework) with the same settings."""

    def __init__(self, max_tokens: int) -> None:
        from agents_core.config import MLLMConfig, VisionConfig  # noqa: PLC0415

        self.image = vision_suite.frame()
        self.vision_config = VisionConfig(enable_local_model=True, local_model_path=str(vision_suite.MODEL),
                                          ncpu_local_model=1, threshold=0.5, warmup=True, log_level="warning")
        self.vlm_config = MLLMConfig(enable_local_model=True, local_model_path=str(TINY_VLM), temperature=0.0,
                                     max_new_tokens=max_tokens, ncpu_local_model=1, warmup=True, log_level="warning")

    def raw(self) -> dict[str, Any]:
        from agents_core.engines.local_llm import LocalVLM  # noqa: PLC0415
        from agents_core.engines.local_vision import LocalVisionModel  # noqa: PLC0415

        if not hasattr(self, "_engines"):
            detector = LocalVisionModel(str(vision_suite.MODEL), ncpu=1, threshold=0.5)
            detector.detect(self.image)
            vlm = LocalVLM(str(TINY_VLM), ncpu=1)
            self._engines = (detector, vlm)
        detector, vlm = self._engines
        start = time.perf_counter()
        found = detector.detect(self.image)
        detected = time.perf_counter()
        labels = ", ".join(str(label) for label in found["labels"]) or "nothing"
        # The MLLM component's own preface of Detections to the question (llm.py, _query_text).
        prompt = f"Objects detected (e2e/seen: {labels}).\n{QUESTION}"
        reply = vlm({"query": [{"role": "user", "content": prompt, "images": [self.image]}], "temperature": 0.0,
                     "max_new_tokens": self.vlm_config.max_new_tokens})["output"]
        done = time.perf_counter()
        return {"loop_ms": (done - start) * 1000, "vision_ms": (detected - start) * 1000,
                "vlm_ms": (done - detected) * 1000, "labels": labels, "answer_chars": len(reply)}

    def framework(self, transport: str, reps: int, record: Callable[[dict[str, Any]], None],
                  raw: Callable[[], dict[str, Any]]) -> None:
        from agents_core import Topic  # noqa: PLC0415
        from agents_core.components import MLLM, Vision  # noqa: PLC0415
        from agents_core.messages import ImageMsg  # noqa: PLC0415

        camera, seen = Topic("e2e/camera", "Image"), Topic("e2e/seen", "Detections")
        question, reply = Topic("e2e/question", "String"), Topic("e2e/reply", "String")
        vision = Vision(inputs=[camera], outputs=[seen], config=self.vision_config, component_name="e2e_eyes")
        vlm = MLLM(inputs=[question, camera, seen], outputs=[reply], trigger=seen, config=self.vlm_config,
                   component_name="e2e_vlm")
        answers: list[float] = []
        labels: list[str] = []
        launcher = _launcher(transport, [vision, vlm])
        with launcher:
            t = launcher.transport
            t.create_subscription(reply, lambda msg: answers.append(time.perf_counter()), inline=True)
            t.create_subscription(seen, lambda msg: labels.append(", ".join(msg.labels)), inline=True)
            time.sleep(0.5)  # Zenoh: the subscriptions reach the publishers
            t.create_publisher(question).publish(QUESTION)
            _wait(lambda: vlm.callbacks["e2e/question"].got_msg, "the question at the VLM")
            publish = t.create_publisher(camera).publish
            msg = ImageMsg(data=self.image, encoding="rgb8")
            for rep in range(reps + 1):  # rep 0: warm-up, not recorded
                raw_run = raw()
                answers.clear()
                start = time.perf_counter()
                publish(msg)
                _wait(lambda: bool(answers), "the VLM's answer")
                took = (answers[0] - start) * 1000
                if rep:
                    record({**raw_run, "mode": "raw", "rep": rep})
                    record({"mode": "framework", "loop_ms": took, "labels": labels[-1] if labels else "", "rep": rep})


def run_child(loop: str, transports: list[str], reps: int, max_tokens: int) -> None:
    runner: Any = VoiceLoop(max_tokens) if loop == "voice" else PerceptionLoop(max_tokens)
    for transport in transports:
        def record(r: dict[str, Any], transport: str = transport) -> None:
            emit({"suite": "e2e", "transport": transport, "payload": f"{loop}_loop", **r})

        runner.framework(transport, reps, record, runner.raw)


def run_suite(settings: dict[str, Any], children: Children,
              progress: Callable[[str], None]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """Both loops, each in its own child (raw and framework alternating); (records, skipped)."""
    records: list[dict[str, Any]] = []
    skipped: list[dict[str, str]] = []
    transports = list(settings.get("e2e_transports", ("memory", "zenoh")))
    for loop in ("voice", "perception"):
        reason = unavailable_reason(loop)
        if reason is not None:
            progress(f"e2e {loop}: skipped: {reason}")
            skipped.append({"suite": "e2e", "transport": ",".join(transports), "mode": loop, "reason": reason})
            continue
        try:
            child = children.start(f"e2e_{loop}", ["-m", "benchmarks.e2e", "--loop", loop, "--transports",
                                                   ",".join(transports), "--reps", str(settings.get("e2e_reps", 1)),
                                                   "--max-tokens", str(settings.get("e2e_max_tokens", 24))],
                                   child_env())
            got = list(child.records(timeout=600))
            children.stop(child)
            records += got
            for r in got:
                progress(f"{'e2e':<10} {r['transport']:<6} {r['mode']:<9} {r['payload']}: {r['loop_ms']:8.1f} ms")
        except ChildFailed as exc:
            progress(f"e2e {loop}: FAILED: {str(exc).splitlines()[0]}")
            skipped.append({"suite": "e2e", "transport": ",".join(transports), "mode": loop,
                            "reason": str(exc)[-1500:]})
    return records, skipped


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--loop", choices=["voice", "perception"], required=True)
    parser.add_argument("--transports", default="memory,zenoh")
    parser.add_argument("--reps", type=int, default=1)
    parser.add_argument("--max-tokens", type=int, default=24)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr)
    run_child(args.loop, [t for t in args.transports.split(",") if t], args.reps, args.max_tokens)
    log(f"e2e {args.loop} done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
