"""VideoMessageMaker: still frames make no clip, a moving square makes one clip within the frame limits."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import pytest

from agents_core import Launcher, Topic
from agents_core.components import VideoMessageMaker
from agents_core.config import VideoMessageMakerConfig
from agents_core.errors import ConfigError, WiringError
from agents_core.messages import Header, ImageMsg, VideoMsg

from ..conftest import wait_for

CAMERA, CLIPS = Topic("camera", "Image"), Topic("clips", "Video")


def _frame(n: int, square_at: int | None) -> ImageMsg:
    pixels = np.full((120, 160, 3), 30, np.uint8)
    if square_at is not None:
        pixels[40:70, square_at:square_at + 30] = 250
    return ImageMsg(data=pixels, encoding="rgb8", header=Header(stamp_ns=1_000_000_000 + n, frame_id="cam"))


@contextmanager
def _maker(config: VideoMessageMakerConfig) -> Iterator[tuple[VideoMessageMaker, list[VideoMsg], Any]]:
    maker = VideoMessageMaker(inputs=[CAMERA], outputs=[CLIPS], config=config)
    launcher = Launcher("memory")
    launcher.add_pkg(components=[maker])
    with launcher:
        clips: list[VideoMsg] = []
        launcher.transport.create_subscription(CLIPS, clips.append)
        yield maker, clips, launcher.transport.create_publisher(CAMERA)


def _feed(maker: VideoMessageMaker, pub: Any, frames: list[ImageMsg]) -> None:
    for frame in frames:
        before = maker.worker_statistics().executed
        pub.publish(frame)
        # One frame at a time: the maker must see every frame (its queue would drop the oldest).
        assert wait_for(lambda b=before: maker.worker_statistics().executed > b)


def test_still_frames_make_no_clip() -> None:
    with _maker(VideoMessageMakerConfig(min_video_frames=3, max_video_frames=20)) as (maker, clips, pub):
        _feed(maker, pub, [_frame(n, 50) for n in range(15)])
    assert clips == [] and maker.videos_published == 0


def test_a_moving_square_makes_one_clip_within_the_limits() -> None:
    config = VideoMessageMakerConfig(min_video_frames=5, max_video_frames=40, max_still_frames=2)
    still = [_frame(n, 10) for n in range(5)]
    moving = [_frame(5 + n, 10 + 8 * (n + 1)) for n in range(12)]
    after = [_frame(17 + n, 10 + 8 * 12) for n in range(8)]
    with _maker(config) as (maker, clips, pub):
        _feed(maker, pub, still + moving + after)
        assert wait_for(lambda: len(clips) == 1)
    clip = clips[0]
    assert config.min_video_frames <= len(clip.frames) <= config.max_video_frames
    # The moving frames and the tolerated still ones that followed them.
    assert len(clip.frames) == len(moving) + config.max_still_frames
    assert clip.header.stamp_ns == moving[0].header.stamp_ns and clip.header.frame_id == "cam"
    assert maker.videos_published == 1


def test_long_motion_is_cut_at_max_frames_and_short_motion_is_dropped() -> None:
    config = VideoMessageMakerConfig(min_video_frames=4, max_video_frames=6, max_still_frames=0)
    long_run = [_frame(n, 5 + 4 * n) for n in range(14)]
    short = [_frame(100 + n, 120 - 20 * n) for n in range(3)]
    with _maker(config) as (maker, clips, pub):
        _feed(maker, pub, [*long_run, _frame(50, 5 + 4 * 13), _frame(51, 5 + 4 * 13)])
        _feed(maker, pub, [*short, _frame(200, 80), _frame(201, 80)])
    assert [len(c.frames) for c in clips] == [6, 6]
    assert maker.clips_dropped >= 1


def test_config_and_wiring_errors() -> None:
    with pytest.raises(ConfigError, match="min_video_frames"):
        VideoMessageMakerConfig(min_video_frames=10, max_video_frames=5)
    with pytest.raises(WiringError):
        VideoMessageMaker(inputs=[CAMERA], outputs=[Topic("text", "String")])
