"""``VideoMessageMakerConfig``: the settings of ``VideoMessageMaker`` (:mod:`.video_maker`), beside it.

Public as ``agents_core.config.VideoMessageMakerConfig`` (re-exported there on first use); importing this module
does not import the component.
"""

from __future__ import annotations

from typing import Any, Literal

import attrs
from attrs import define, field

from .. import base_validators
from ..config import BaseComponentConfig
from ..errors import ConfigError

__all__ = ["VideoMessageMakerConfig"]


def _video_frames_order(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    low = value if attribute.name == "min_video_frames" else getattr(instance, "min_video_frames", 1)
    high = value if attribute.name == "max_video_frames" else getattr(instance, "max_video_frames", low)
    if low > high:
        raise ConfigError(f"{type(instance).__name__}: min_video_frames ({low}) must not exceed "
                          f"max_video_frames ({high})")


@define(kw_only=True)
class VideoMessageMakerConfig(BaseComponentConfig):
    """Settings of the :class:`~agents_core.components.video_maker.VideoMessageMaker` component.

    :param min_video_frames: a clip with fewer frames when the motion stops is dropped.
    :param max_video_frames: a clip is published when it reaches this many frames (a new one starts).
    :param motion_estimation_func: ``"frame_difference"`` (a frame moves when it differs enough from
        the previous one), or None (every frame counts as motion: clips of ``max_video_frames``).
    :param threshold: percent of the pixels that must change for a frame to count as motion.
    :param pixel_threshold: how much (grey levels, 0..255) a pixel must change to count as changed.
    :param max_still_frames: still frames a clip may contain before it ends (they stay in the clip).
    """

    min_video_frames: int = field(default=15, validator=[base_validators.in_range(1, 100_000), _video_frames_order])
    max_video_frames: int = field(default=600, validator=[base_validators.in_range(1, 100_000), _video_frames_order])
    motion_estimation_func: Literal["frame_difference"] | None = field(
        default="frame_difference", validator=base_validators.in_(["frame_difference", None]))
    threshold: float = field(default=0.5, validator=base_validators.in_range(0.0, 100.0))
    pixel_threshold: int = field(default=25, validator=base_validators.in_range(1, 255))
    max_still_frames: int = field(default=3, validator=base_validators.in_range(0, 100_000))

    def _get_inference_params(self) -> dict[str, Any]:
        """None: this component calls no model (every config class has the hook, architecture.md)."""
        return {}

