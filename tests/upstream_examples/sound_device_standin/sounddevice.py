"""A stand-in for the ``sounddevice`` module (PortAudio): one output device that records what it plays.

Upstream's complete_agent asks ``TextToSpeechConfig(play_on_device=True)``; a test machine has no
sound card. Put this folder first on ``sys.path`` (or ``PYTHONPATH`` for a recipe's processes) and
the TextToSpeech component plays here; ``played`` holds (sample count, rate) per clip.
"""

from __future__ import annotations

from typing import Any

played: list[tuple[int, int]] = []


def query_devices(device: Any = None, kind: str | None = None) -> dict[str, Any]:
    """The one device, whatever is asked for."""
    return {"name": "stand-in", "max_output_channels": 2, "default_samplerate": 16000.0}


def play(data: Any, samplerate: int, device: Any = None) -> None:
    """Record the clip instead of playing it."""
    played.append((len(data), int(samplerate)))


def wait() -> None:
    """Playing is instant here."""


def stop() -> None:
    """Nothing is playing."""
