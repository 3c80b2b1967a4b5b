"""The voice-loop recipe (voice_recipe.py) on memory, Zenoh and ROS 2, and the voice demo.

A spoken question streamed in 20 ms Audio chunks comes back as spoken Audio: SpeechToText (Whisper
tiny.en + Silero VAD) -> LLM (SmolLM2) -> TextToSpeech (Piper). Memory runs in this process; each
cross-process transport (the ``recipe_transport`` fixture: Zenoh, ROS 2) runs the recipe in a child
process, and on ROS 2 a plain rclpy node sends agents_interfaces/Audio and reads the transcript and
the spoken answer.
"""

from __future__ import annotations

import re
import subprocess
import sys
import threading
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core.testing.pairs import skip_unless_installed
from agents_core.testing.recipes import RecipeTransport, run_recipe
from agents_core.transport.contract import Transport

from ..conftest import wait_for
from . import voice_recipe
from .models_dir import REPO
from .voice_recipe import HEARD, MIC, SPOKEN, chunks, clip, needs_voice_loop, silence

pytestmark = pytest.mark.local_models

QUESTION = np.concatenate([silence(0.3), clip("pick_up_red_cube_16k.wav"), silence(1.0)])


def _check(transport: Transport) -> None:
    heard: list[str] = []
    spoken: list[Any] = []
    subs = [transport.create_subscription(HEARD, heard.append, inline=True),
            transport.create_subscription(SPOKEN, spoken.append, inline=True)]
    mic = transport.create_publisher(MIC)
    try:
        deadline = time.monotonic() + 40
        # Discovery may lose the first chunks on a network transport: send the question until heard.
        while not heard and time.monotonic() < deadline:
            for msg in chunks(QUESTION):
                mic.publish(msg)
            wait_for(lambda: bool(heard), timeout=8)
        assert heard and "red cube" in heard[0].lower(), heard
        assert wait_for(lambda: sum(a.duration for a in spoken) > 0.5, timeout=40), "no spoken answer"
        assert spoken[0].sample_rate == 22_050
    finally:
        mic.close()
        for sub in subs:
            sub.close()


def test_voice_loop_on_memory() -> None:
    needs_voice_loop()
    with voice_recipe.build("memory") as launcher:
        _check(launcher.transport)


def _ask_through_the_framework(recipe_transport: RecipeTransport) -> None:
    _check(recipe_transport.open_asker())


#: How a user of each transport talks to the recipe; the framework's own transport where none is named.
USER_SIDE: dict[str, Callable[[RecipeTransport], None]] = {"ros2": lambda _: _plain_rclpy_side()}


def test_voice_loop_in_its_own_process(recipe_transport: RecipeTransport, tmp_path: Path) -> None:
    needs_voice_loop()
    if recipe_transport.name == "ros2":
        skip_unless_installed("ros2", "agents_interfaces")
    with run_recipe("tests.components.voice_recipe", recipe_transport, tmp_path, cwd=REPO, ready_timeout=90):
        USER_SIDE.get(recipe_transport.name, _ask_through_the_framework)(recipe_transport)


def _plain_rclpy_side() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # lark (via rosidl) imports sre_parse
        import rclpy  # noqa: PLC0415
        import rosidl_generator_py  # noqa: F401, PLC0415
        from agents_interfaces.msg import Audio  # noqa: PLC0415
        from rclpy.executors import SingleThreadedExecutor  # noqa: PLC0415
        from std_msgs.msg import String  # noqa: PLC0415

    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("plain_voice_user", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    heard: list[str] = []
    spoken: list[Any] = []
    node.create_subscription(String, "/heard", lambda m: heard.append(m.data), 10)
    node.create_subscription(Audio, "/spoken", spoken.append, 1000)
    mic = node.create_publisher(Audio, "/mic", 1000)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        deadline = time.monotonic() + 40

        def understood() -> bool:
            return any(re.search("red cube", text, re.IGNORECASE) for text in heard)

        # Discovery may cut the first utterance short (chunks sent before the match are lost):
        # say it again, a bounded number of times, until it is understood.
        while not understood() and time.monotonic() < deadline:
            before = len(heard)
            for msg in chunks(QUESTION):
                out = Audio(sample_rate=16_000, channels=1, format="S16LE")
                out.data = msg.data.astype("<i2").tobytes()
                mic.publish(out)
                time.sleep(0.002)  # a little pacing: the default QoS history keeps 1000 messages
            wait_for(lambda before=before: len(heard) > before, timeout=8)
        assert understood(), heard
        assert wait_for(lambda: len(spoken) >= 5, timeout=40), "no spoken answer on /spoken"
        assert spoken[0].format == "S16LE" and spoken[0].sample_rate == 22_050
    finally:
        executor.shutdown()
        spinner.join(timeout=5)
        node.destroy_node()
        rclpy.shutdown(context=context)


def test_voice_demo_prints_the_transcript_and_the_answer_and_writes_the_spoken_answer(tmp_path: Path) -> None:
    needs_voice_loop()
    wav = tmp_path / "question.wav"
    from agents_core.engines.audio import write_wav  # noqa: PLC0415

    write_wav(wav, clip("pick_up_red_cube_16k.wav"), 16_000)
    out = tmp_path / "answer.wav"
    result = subprocess.run([sys.executable, "-m", "agents_core.demo", "voice", "--wav", str(wav), "--out", str(out),
                             "--stt-model", str(voice_recipe.WHISPER_DIR), "--vad-model", str(voice_recipe.VAD_FILE),
                             "--voice", str(voice_recipe.voice_dir()), "--max-new-tokens", "24"],
                            capture_output=True, text=True, timeout=180, check=False, cwd=REPO)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    assert re.search(r"Heard: .*red cube", result.stdout, re.IGNORECASE), result.stdout
    assert "A: " in result.stdout and out.is_file() and out.stat().st_size > 10_000, result.stdout
