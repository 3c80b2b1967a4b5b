"""The voice demo as the README gives it: the user's WAV in, a transcript, an answer and its speech out.

It runs ``python -m agents_core.demo voice`` with only ``--wav`` and the models the demo would
otherwise fetch (Whisper from the shared folder; the default VAD found as the ``silero-vad``
package ships it; the default Piper voice), so the demo's own defaults are what is tested. A
default that changed under it (``enable_vad`` off unless a VAD path is given) once made it hear
nothing and then crash in the recognizer.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from .components.voice_recipe import SHARED_AUDIO, VAD_FILE, WHISPER_DIR, voice_dir

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.local_models
@pytest.mark.slow
def test_the_voice_demo_hears_answers_and_speaks(tmp_path: Path) -> None:
    voice = voice_dir()  # skips, naming what is missing, without the voice or the speech models
    package = tmp_path / "site" / "silero_vad"  # as `pip install --no-deps silero-vad` lays it out
    (package / "data").mkdir(parents=True)
    (package / "__init__.py").write_text("raise ImportError('never imported: it would import torch')\n")
    shutil.copy(VAD_FILE, package / "data" / "silero_vad.onnx")

    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path / "site"), str(ROOT / "src")])}
    out = tmp_path / "answer.wav"
    result = subprocess.run(
        [sys.executable, "-m", "agents_core.demo", "voice", "--wav", str(SHARED_AUDIO / "pick_up_red_cube_16k.wav"),
         "--out", str(out), "--stt-model", str(WHISPER_DIR), "--voice", str(voice)],
        check=False, capture_output=True, text=True, timeout=300, cwd=tmp_path, env=env)
    assert result.returncode == 0, result.stdout + result.stderr[-3000:]
    heard = next((line for line in result.stdout.splitlines() if line.startswith(("Heard", "Q:"))), "")
    assert "red cube" in heard.lower(), result.stdout
    assert "Spoke" in result.stdout and out.stat().st_size > 16_000, result.stdout
