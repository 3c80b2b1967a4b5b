"""Recording a camera input into an animated GIF with Pillow: the work behind ``Vision.record_video``.

:func:`record_frames` samples the latest frame of one input at up to ``fps`` frames per second
for ``duration`` seconds; each new frame is kept as a palette image (one byte a pixel, so a
recording costs about ``width x height`` bytes a frame, bounded by :data:`MAX_RECORDING_BYTES`).
:func:`write_gif` writes them with their real spacing as frame durations, atomically: the file
appears complete or not at all. GIF needs only Pillow (no video codec library), plays in every
browser and image viewer, and keeps timing; its 256-colour palette per frame is the price.
"""

from __future__ import annotations

import itertools
import os
import re
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Final

import numpy as np
import numpy.typing as npt

from ...errors import AlgorithmFailure, ConfigError
from ...support.install_hint import install_hint

__all__ = ["MAX_FPS", "MAX_RECORDING_BYTES", "MAX_RECORDING_S", "RecordedFrame", "confined_folder",
           "record_frames", "recording_path", "write_gif"]

#: The longest recording one call may ask for (s).
MAX_RECORDING_S: Final[float] = 3600.0
#: The highest frame rate: GIF frame durations are in 1/100 s, and players clamp shorter ones.
MAX_FPS: Final[int] = 50
#: The most pixel bytes a recording keeps; it stops early (logged) when the next frame would pass it.
MAX_RECORDING_BYTES: Final[int] = 512 * 1024 * 1024

#: One recorded frame: when it was sampled (monotonic s) and its palette image.
RecordedFrame = tuple[float, Any]


def _pillow() -> Any:
    try:
        from PIL import Image as PILImage  # noqa: PLC0415  (optional: only recording needs it)
    except ImportError as exc:
        raise AlgorithmFailure("recording a video needs Pillow: pip install pillow "
                               f"(or {install_hint('local')})") from exc
    return PILImage


def confined_folder(base: str, wanted: str | None, what: str) -> str:
    """The folder ``wanted`` (None: ``base``), refused unless it lies inside ``base`` once resolved.

    ``~`` is expanded in both; a relative ``wanted`` is taken inside ``base``; symbolic links are
    followed before the check, so a link inside ``base`` that leads out of it is refused too.
    """
    root = Path(base).expanduser().resolve()
    if wanted is None:
        return str(root)
    if not isinstance(wanted, str) or not wanted or "\x00" in wanted:
        raise ConfigError(f"{what}: save_path must be a folder name, got {str(wanted)[:200]!r}")
    given = Path(wanted).expanduser()
    folder = (given if given.is_absolute() else root / given).resolve()
    if folder != root and root not in folder.parents:
        raise ConfigError(f"{what}: save_path {wanted[:200]!r} is outside the configured folder {str(root)!r} "
                          "(config.recordings_dir)")
    return str(folder)


def recording_path(folder: str, source: str) -> Path:
    """``<folder>/recording_<source>_<time>.gif`` (the folder is created; ``~`` is expanded)."""
    directory = Path(folder).expanduser()
    directory.mkdir(parents=True, exist_ok=True)
    stem = re.sub(r"[^A-Za-z0-9_.-]", "_", source)
    return directory / f"recording_{stem}_{time.strftime('%Y%m%d_%H%M%S')}_{time.time_ns() % 10**9:09d}.gif"


def record_frames(latest: Callable[[], tuple[int, Any]], to_rgb: Callable[[Any], npt.NDArray[np.uint8]],
                  duration: float, fps: int, stop: Callable[[], bool] = lambda: False,
                  max_bytes: int = MAX_RECORDING_BYTES) -> tuple[list[RecordedFrame], str]:
    """Sample frames for ``duration`` seconds; returns them and why recording ended early ("" if it did not).

    ``latest()`` gives ``(arrivals so far, latest value)``; a frame is taken only when the count
    has changed since the last sample, so a camera slower than ``fps`` is not padded with copies
    (its frames simply last longer). ``to_rgb`` turns a value into RGB pixels; a value it refuses
    (AlgorithmFailure: a depth-only frame, an oversized one) is skipped. ``stop()`` ends it early.
    """
    image_module = _pillow()
    frames: list[RecordedFrame] = []
    period, kept_bytes, last_count = 1.0 / fps, 0, -1
    start = time.monotonic()
    deadline = start + duration
    next_sample = start
    while (now := time.monotonic()) < deadline:
        if stop():
            return frames, "the component stopped"
        if now < next_sample:
            time.sleep(min(next_sample, deadline) - now)
            continue
        next_sample += period
        count, value = latest()
        if count == last_count or value is None:
            continue
        last_count = count
        try:
            pixels = to_rgb(value)
        except AlgorithmFailure:
            continue
        if kept_bytes + pixels.shape[0] * pixels.shape[1] > max_bytes:
            return frames, f"the recording reached {max_bytes} bytes of frames"
        kept_bytes += pixels.shape[0] * pixels.shape[1]
        # Quantized now: a palette image is a third of the RGB frame, and GIF needs one anyway. Fast
        # octree: ~5 ms for 512x512, where Pillow's default (median cut) takes ~450 ms and drops frames.
        frames.append((now, image_module.fromarray(np.ascontiguousarray(pixels)).quantize(
            colors=256, method=image_module.Quantize.FASTOCTREE)))
    return frames, ""


def write_gif(frames: list[RecordedFrame], path: Path, fps: int, end: float | None = None) -> Path:
    """Write ``frames`` to ``path`` as a looping GIF whose frame durations are the real gaps between them.

    The last frame lasts until ``end`` (the recording's end, monotonic s), else one frame period.
    Frames of another size than the first are resized to it (a camera that changed resolution).
    Written to a temporary name beside ``path`` and renamed, so a reader never sees half a file.
    """
    if not frames:
        raise AlgorithmFailure(f"no frames to write to {path}")
    size = frames[0][1].size
    images = [img if img.size == size else img.resize(size) for _, img in frames]
    times = [t for t, _ in frames] + [end if end is not None else frames[-1][0] + 1.0 / fps]
    # GIF stores durations in 1/100 s; anything under 20 ms is played slower by most viewers anyway.
    durations = [max(20, round((b - a) * 1000)) for a, b in itertools.pairwise(times)]
    partial = path.with_name(f".{path.name}.partial")
    try:
        images[0].save(partial, format="GIF", save_all=True, append_images=images[1:], duration=durations,
                       loop=0, optimize=False)
        os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)
    return path
