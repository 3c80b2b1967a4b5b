"""``Thumbnails``: a few frames evenly spaced over an episode of unknown length, in bounded memory.

Frames are kept at a stride that doubles whenever the store fills, so at most ``4 * count`` frames
are held whatever the episode's length; :meth:`Thumbnails.write` picks ``count`` of them evenly
and writes them as small JPEG files (Pillow; none are written without it).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["Thumbnails"]


class Thumbnails:
    """Keeps frames of the first camera (see the module docs)."""

    def __init__(self, count: int) -> None:
        self.count = count
        self._frames: list[Any] = []
        self._stride = 1
        self._seen = 0
        self._last: Any = None

    def add(self, frames: Mapping[str, Any]) -> None:
        """Offer this step's camera frames (the first camera's is kept when its turn comes)."""
        if self.count == 0 or not frames:
            return
        self._last = next(iter(frames.values()))
        if self._seen % self._stride == 0:
            self._frames.append(next(iter(frames.values())))
            if len(self._frames) >= 4 * self.count:
                self._frames = self._frames[::2]
                self._stride *= 2
        self._seen += 1

    def chosen(self) -> list[Any]:
        """Up to ``count`` frames, evenly spaced, the episode's first and last included."""
        frames = list(self._frames)
        if self._last is not None and (not frames or frames[-1] is not self._last):
            frames.append(self._last)
        if len(frames) <= self.count:
            return frames
        picks = np.linspace(0, len(frames) - 1, self.count).round().astype(int)
        return [frames[i] for i in picks]

    def write(self, directory: Path, prefix: str) -> list[str]:
        """Write the chosen frames as ``<directory>/<prefix>_NN.jpg``; their paths relative to ``directory.parent``."""
        chosen = self.chosen()
        if not chosen:
            return []
        try:
            from PIL import Image  # noqa: PLC0415 - optional
        except ImportError:
            return []
        directory.mkdir(parents=True, exist_ok=True)
        names = []
        for i, frame in enumerate(chosen):
            path = directory / f"{prefix}_{i:02d}.jpg"
            pixels = frame[:, :, 0] if frame.shape[2] == 1 else frame
            Image.fromarray(np.ascontiguousarray(pixels)).save(path, quality=80)
            names.append(f"{directory.name}/{path.name}")
        return names
