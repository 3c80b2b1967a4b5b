"""``VideoMessageMaker``: groups camera frames into Video messages by motion.

Each Image that arrives is compared with the one before it (``motion_estimation_func=
"frame_difference"``: the share of pixels whose grey level changed by more than
``pixel_threshold`` must reach ``threshold`` percent). A moving frame starts a clip or extends it;
still frames extend a running clip up to ``max_still_frames`` in a row, and one more ends it. A clip
that ended with at least ``min_video_frames`` frames is published as one Video; a shorter one is
dropped. A clip that reaches ``max_video_frames`` is published at once and a new one starts, so a
scene that never stops moving still yields videos. The Video keeps the header of its first frame.

A Video output can feed a VLM, or be recorded.
"""

from __future__ import annotations

from collections.abc import Sequence
from types import MappingProxyType
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import AlgorithmFailure
from ..messages import ImageMsg, VideoMsg
from ..supported_types import Image, Video
from ..topics import Topic
from .component_base import AllowedTypes, Component, TriggerType
from .video_maker_config import VideoMessageMakerConfig

__all__ = ["VideoMessageMaker", "motion_fraction"]

# Frames are compared at most this size (a side): motion is a coarse property, and it keeps each
# frame's cost small whatever the camera's resolution.
_COMPARE_SIDE = 160


def _grey_small(image: ImageMsg) -> npt.NDArray[np.int16]:
    pixels = image.to_rgb()
    step = max(1, int(np.ceil(max(pixels.shape[:2]) / _COMPARE_SIDE)))
    small = pixels[::step, ::step]
    if small.dtype != np.uint8:  # 16-bit mono / depth: compare on the 8 most significant bits
        small = (small >> 8).astype(np.uint8)
    grey = small.mean(axis=2) if small.shape[2] > 1 else small[:, :, 0]
    return np.asarray(grey, np.int16)


def motion_fraction(previous: npt.NDArray[Any], current: npt.NDArray[Any], pixel_threshold: int) -> float:
    """Percent of pixels whose grey level differs by more than ``pixel_threshold`` between two frames."""
    if previous.shape != current.shape:
        return 100.0  # the camera changed resolution: treat as motion
    changed = np.abs(current.astype(np.int16) - previous.astype(np.int16)) > pixel_threshold
    return 100.0 * float(changed.mean()) if changed.size else 0.0


class VideoMessageMaker(Component):
    """Publishes Video messages of the moving parts of an Image stream (see the module docs).

    :param inputs: one Image topic.
    :param outputs: one or more Video topics.
    :param config: a :class:`~agents_core.config.VideoMessageMakerConfig`.
    :param trigger: the Image topic (default: the input).
    """

    config_class = VideoMessageMakerConfig
    allowed_inputs: AllowedTypes | None = MappingProxyType({"Required": [Image]})
    allowed_outputs: AllowedTypes | None = MappingProxyType({"Required": [Video]})

    def __init__(
        self,
        inputs: Sequence[Topic] | None = None,
        outputs: Sequence[Topic] | None = None,
        config: VideoMessageMakerConfig | None = None,
        trigger: TriggerType | None = None,
        component_name: str = "video_maker",
        **kwargs: Any,
    ) -> None:
        if trigger is None and inputs:
            trigger = list(inputs)
        super().__init__(inputs=inputs, outputs=outputs, config=config, trigger=trigger,
                         component_name=component_name, **kwargs)
        self.config: VideoMessageMakerConfig
        self._clip: list[ImageMsg] = []
        self._still = 0
        self._previous: npt.NDArray[np.int16] | None = None
        #: Clips published and dropped (too short) so far.
        self.videos_published = 0
        self.clips_dropped = 0

    def custom_on_deactivate(self) -> None:
        self._clip, self._still, self._previous = [], 0, None

    def _is_moving(self, frame: ImageMsg) -> bool:
        if self.config.motion_estimation_func is None:
            return True
        grey = _grey_small(frame)
        previous, self._previous = self._previous, grey
        if previous is None:
            return False
        return motion_fraction(previous, grey, self.config.pixel_threshold) >= self.config.threshold

    def _execution_step(self, **kwargs: Any) -> None:
        topic = kwargs.get("topic")
        callbacks = {**self.callbacks, **self.trig_callbacks}
        cb = callbacks[topic.name] if topic is not None else next(iter(callbacks.values()))
        frame = cb.msg
        if frame is None:
            return
        if not isinstance(frame, ImageMsg) or frame.height == 0 or frame.width == 0:
            raise AlgorithmFailure(f"component {self.component_name!r}: cannot compare an empty frame")
        moving = self._is_moving(frame)
        if moving:
            self._clip.append(frame)
            self._still = 0
        elif self._clip:
            self._still += 1
            if self._still > self.config.max_still_frames:
                self._end_clip()
                return
            self._clip.append(frame)
        if len(self._clip) >= self.config.max_video_frames:
            self._end_clip()

    def _end_clip(self) -> None:
        clip, self._clip, self._still = self._clip, [], 0
        if len(clip) < self.config.min_video_frames:
            self.clips_dropped += 1
            self._logger.debug("dropped a clip of %d frame(s) (min_video_frames=%d)", len(clip),
                               self.config.min_video_frames)
            return
        video = VideoMsg(frames=list(clip), header=clip[0].header)
        for pub in self.publishers_dict.values():
            pub.publish(video)
        self.videos_published += 1
