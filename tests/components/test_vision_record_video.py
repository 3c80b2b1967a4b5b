"""``Vision.record_video(topic_name, duration, save_path, fps)`` (upstream's action) on the memory
transport: the shared photos streamed as a camera become an animated GIF with their timing."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest

from agents_core import Topic
from agents_core.components import Vision
from agents_core.config import VisionConfig
from agents_core.errors import AlgorithmFailure, ConfigError, WiringError
from agents_core.messages import ImageMsg

from ..conftest import wait_for
from .test_llm import running
from .vision_recipe import needs_ssd, photo

pytestmark = pytest.mark.local_models

CAMERA, OTHER_CAMERA = Topic("camera", "Image"), Topic("other_camera", "Image")
PHOTOS = ("astronaut.png", "chelsea.png", "coffee.png", "motorcycle_left.png")


def _vision(folder: Path) -> Vision:
    return Vision(inputs=[CAMERA, OTHER_CAMERA], outputs=[Topic("objects", "Detections")],
                  config=VisionConfig(enable_local_model=True, local_model_path=needs_ssd(),
                                      recordings_dir=str(folder)))


def _stream(publish: object, frames: list[np.ndarray], period: float, stop: threading.Event) -> None:
    i = 0
    while not stop.is_set():
        publish(ImageMsg(data=frames[i % len(frames)], encoding="rgb8"))  # type: ignore[operator]
        i += 1
        stop.wait(period)


def _same_size(name: str, shape: tuple[int, int]) -> np.ndarray:
    from PIL import Image as PILImage  # noqa: PLC0415

    return np.asarray(PILImage.fromarray(photo(name)).resize((shape[1], shape[0])))


def test_record_video_writes_the_camera_frames_as_an_animated_gif(tmp_path: Path) -> None:
    from PIL import Image as PILImage  # noqa: PLC0415

    vision = _vision(tmp_path)
    first = photo(PHOTOS[0])
    frames = [first] + [_same_size(n, first.shape[:2]) for n in PHOTOS[1:]]
    stop = threading.Event()
    with running(vision) as launcher:
        publish = launcher.transport.create_publisher(OTHER_CAMERA).publish
        feeder = threading.Thread(target=_stream, args=(publish, frames, 0.1, stop), daemon=True)
        feeder.start()
        try:
            assert wait_for(lambda: vision.trig_callbacks["other_camera"].got_msg)
            started = time.monotonic()
            path = vision.record_video("other_camera", duration=1.5, save_path=str(tmp_path / "videos"), fps=10,
                                       wait=True)
            took = time.monotonic() - started
        finally:
            stop.set()
            feeder.join(5)
    saved = Path(path)
    assert saved.parent == tmp_path / "videos" and saved.suffix == ".gif" and "other_camera" in saved.name
    assert 1.4 < took < 10, took
    assert list(saved.parent.iterdir()) == [saved]  # no partial file left beside it
    with PILImage.open(saved) as gif:
        assert gif.format == "GIF" and gif.size == (first.shape[1], first.shape[0])
        n = gif.n_frames
        durations, firsts = [], []
        for k in range(n):
            gif.seek(k)
            durations.append(gif.info["duration"])
            firsts.append(np.asarray(gif.convert("RGB")).astype(int))
    # ~15 frames arrived in 1.5 s at 10 per second; a loaded machine may lose a few samples.
    assert 5 <= n <= 16, (n, durations)
    assert 1.0 < sum(durations) / 1000 < 2.5, durations
    # The frames are the photos (palette-quantized: close, not equal), in the order sent.
    seen = {int(np.argmin([np.abs(f - p).mean() for p in frames])) for f in firsts}
    assert len(seen) >= 3, seen
    assert min(np.abs(firsts[0] - p).mean() for p in frames) < 12


def test_record_video_returns_at_once_and_the_file_appears_complete(tmp_path: Path) -> None:
    from PIL import Image as PILImage  # noqa: PLC0415

    vision = _vision(tmp_path)
    stop = threading.Event()
    with running(vision) as launcher:
        publish = launcher.transport.create_publisher(CAMERA).publish
        feeder = threading.Thread(target=_stream, args=(publish, [photo("chelsea.png")], 0.05, stop), daemon=True)
        feeder.start()
        try:
            assert wait_for(lambda: vision.trig_callbacks["camera"].got_msg)
            started = time.monotonic()
            path = Path(vision.record_video(duration=0.6, save_path=str(tmp_path), fps=20))  # upstream: non-blocking
            assert time.monotonic() - started < 0.5
            assert wait_for(path.exists, timeout=10)
        finally:
            stop.set()
            feeder.join(5)
    with PILImage.open(path) as gif:
        # One photo over and over: Pillow merges identical frames, their durations add up.
        total = 0
        for k in range(gif.n_frames):
            gif.seek(k)
            total += gif.info["duration"]
    assert 0.4 < total / 1000 < 1.5 and "camera" in path.name, total


def test_record_video_refuses_bad_arguments_and_reports_no_frames(tmp_path: Path) -> None:
    vision = _vision(tmp_path)
    with running(vision):
        with pytest.raises(WiringError, match="not one of its cameras"):
            vision.record_video("nowhere", save_path=str(tmp_path))
        for bad in ({"duration": 0}, {"duration": -1.0}, {"duration": 1e9}, {"fps": 0}, {"fps": 1000},
                    {"fps": 2.5}):
            with pytest.raises(ConfigError):
                vision.record_video("camera", save_path=str(tmp_path), **bad)  # type: ignore[arg-type]
        with pytest.raises(AlgorithmFailure, match="no frame arrived"):
            vision.record_video("camera", duration=0.2, save_path=str(tmp_path), wait=True)
    assert list(tmp_path.iterdir()) == []
