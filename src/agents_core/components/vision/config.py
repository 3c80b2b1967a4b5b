"""``VisionConfig``: the settings of ``Vision`` (:mod:`agents_core.components.vision.component`), beside it.

Public as ``agents_core.config.VisionConfig`` (re-exported there on first use); importing this module
does not import the component.
"""

from __future__ import annotations

from typing import Any

import attrs
from attrs import define, field

from ... import base_validators
from ...config import AT_CONFIGURE, ModelComponentConfig
from ...errors import ConfigError

__all__ = ["VisionConfig"]


def _optional_labels(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    if value is None:
        return
    ok = (isinstance(value, list) and all(isinstance(v, str) for v in value)) or (
        isinstance(value, dict) and all(isinstance(k, int) and not isinstance(k, bool) and isinstance(v, str)
                                        for k, v in value.items()))
    if not ok:
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must be None, a list of str or a dict "
                          f"int -> str, got {value!r:.200}")


def _optional_str_list(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    if value is not None and not (isinstance(value, list) and all(isinstance(v, str) and v for v in value)):
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must be None or a list of non-empty str, "
                          f"got {value!r:.200}")


@define(kw_only=True)
class VisionConfig(ModelComponentConfig):
    """Settings of the :class:`~agents_core.components.vision.Vision` component.

    :param threshold: minimum score of a published detection.
    :param nms_threshold: the local model's non-maximum suppression IoU (same-class boxes overlapping more
        than this are merged into the best one).
    :param get_dataset_labels: publish class names (False: class ids as text).
    :param labels_to_track: the labels Trackings outputs follow (None: every label); the ``track``
        action changes it at run time.
    :param enable_visualization: publish each frame with its boxes and labels drawn on the Image output.
    :param include_image: put the input image into every Detections / Trackings message.
    :param max_image_side: frames larger than this (pixels, either side) are refused with an error.
    :param tracking_max_age: seconds a tracked object may go unseen and keep its id when it reappears.
    :param tracking_iou_threshold: minimum overlap of a detection with a track's predicted box to continue it.
    :param input_height, input_width: the local model's input size, when the model file does not fix it.
    :param dataset_labels: class names of the local model (a list in class order, or id -> name);
        None: from a labels file beside the model, the model's metadata, or COCO.
    :param dataset_labels_file: a labels file for the local model (see
        :func:`~agents_core.engines.local_vision.read_labels_file`).
    :param recordings_dir: the folder ``record_video`` and ``take_picture`` save into; a ``save_path``
        they are given must lie inside it (a relative one is taken inside it), else refused.
    :param max_recordings: ``record_video`` recordings running at once; one more is refused.
    :param max_recording_bytes: the pixel bytes one recording may keep before it stops early.
    :param enable_local_classifier: upstream's name of ``enable_local_model`` for Vision: True turns
        it on (and reads back whether the local detector is enabled).
    """

    threshold: float = field(default=0.5, validator=base_validators.in_range(0.0, 1.0))
    nms_threshold: float = field(default=0.5, validator=base_validators.in_range(0.0, 1.0), metadata=AT_CONFIGURE)
    get_dataset_labels: bool = field(default=True)
    labels_to_track: list[str] | None = field(default=None, validator=_optional_str_list)
    enable_visualization: bool = field(default=False, metadata=AT_CONFIGURE)
    include_image: bool = field(default=False)
    max_image_side: int = field(default=4096, validator=base_validators.in_range(1, 1 << 20))
    tracking_max_age: float = field(default=1.0, validator=base_validators.in_range(0.0, 3600.0))
    tracking_iou_threshold: float = field(default=0.2, validator=base_validators.in_range(0.0, 1.0))
    input_height: int = field(default=640, validator=base_validators.in_range(1, 8192), metadata=AT_CONFIGURE)
    input_width: int = field(default=640, validator=base_validators.in_range(1, 8192), metadata=AT_CONFIGURE)
    dataset_labels: list[str] | dict[int, str] | None = field(default=None, validator=_optional_labels,
                                                              metadata=AT_CONFIGURE)
    dataset_labels_file: str | None = field(default=None, validator=base_validators.optional_str, metadata=AT_CONFIGURE)
    enable_local_classifier: bool = field(default=False, metadata=AT_CONFIGURE)
    recordings_dir: str = field(default="~/emos/videos", validator=base_validators.non_empty_str)
    max_recordings: int = field(default=2, validator=base_validators.in_range(1, 64))
    max_recording_bytes: int = field(default=268_435_456, validator=base_validators.in_range(1, 1 << 40))  # 256 MiB

    def __attrs_post_init__(self) -> None:
        # One setting under two names: either turns the local detector on, both read the same afterwards.
        self.enable_local_model = self.enable_local_classifier = self.enable_local_model or self.enable_local_classifier

    def _get_inference_params(self) -> dict[str, Any]:
        params: dict[str, Any] = {"threshold": self.threshold, "get_dataset_labels": self.get_dataset_labels}
        if self.labels_to_track:
            params["labels_to_track"] = list(self.labels_to_track)
        return params

