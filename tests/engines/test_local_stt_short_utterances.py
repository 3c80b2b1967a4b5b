"""A few samples of speech (a VAD's cut at the end of a stream) transcribe to nothing, not a crash.

sherpa-onnx 2.0.1's Whisper kills the process with SIGSEGV on fewer than ~100 samples; the voice
demo died that way on a fresh clone. The recognizer runs in a child process here so that a crash
is a test failure with its exit status rather than the end of the test run.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from ..components.voice_recipe import needs_stt

ROOT = Path(__file__).resolve().parents[2]

_SCRIPT = """
import sys
import numpy as np
from agents_core.engines.local_stt import LocalSTT
stt = LocalSTT(sys.argv[1])
for n in (1, 10, 50, 99):
    text = stt.transcribe(np.full(n, 0.05, np.float32), 16000)
    print(n, repr(text), flush=True)
"""


@pytest.mark.local_models
def test_a_handful_of_samples_is_no_crash() -> None:
    whisper, _vad = needs_stt()
    result = subprocess.run([sys.executable, "-c", _SCRIPT, whisper], check=False, capture_output=True, text=True,
                            timeout=120, cwd=ROOT)
    assert result.returncode == 0, f"exit status {result.returncode}: {result.stdout}{result.stderr[-2000:]}"
    assert [line.split()[0] for line in result.stdout.splitlines()] == ["1", "10", "50", "99"]
