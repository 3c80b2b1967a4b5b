"""Perception results: detections, trackings and points of interest on an image, and the multi-source lists."""

from __future__ import annotations

from typing import Any, ClassVar

from attrs import define, field

from ..callbacks import DetectionsCallback
from ..errors import TypeValidationError
from ..support.lazy_numpy import np, npt
from .base import SupportedType
from .fields import Header, Message, header_field, instance_of, is_str_list, named, to_array, wire
from .media import Image, ImageMsg

__all__ = [
    "Detections",
    "DetectionsMsg",
    "DetectionsMultiSource",
    "PointsOfInterest",
    "PointsOfInterestMsg",
    "Trackings",
    "TrackingsMsg",
    "TrackingsMultiSource",
]


def _boxes(value: Any) -> npt.NDArray[np.float32]:
    return to_array(value, np.float32, (None, 4), "boxes")


def _scores(value: Any) -> npt.NDArray[np.float32]:
    return to_array(value, np.float32, (None,), "scores")


def _ids(value: Any) -> npt.NDArray[np.int64]:
    return to_array(value, np.int64, (None,), "ids")


def _centroids(value: Any) -> npt.NDArray[np.float32]:
    return to_array(value, np.float32, (None, 2), "centroids")


def _estimated_velocities(value: Any) -> npt.NDArray[np.float32]:
    return to_array(value, np.float32, (None, 2), "estimated_velocities")


def _points(value: Any) -> npt.NDArray[np.float32]:
    return to_array(value, np.float32, (None, 2), "points")


_BOXES = wire("[[x1, y1, x2, y2] float, ...]", as_list=True)


@named
@define(eq=False)
class DetectionsMsg(Message):
    """Object detections: ``boxes`` Nx4 (x1, y1, x2, y2 pixels), ``labels`` and ``scores`` of N."""

    boxes: npt.NDArray[np.float32] = field(factory=lambda: np.zeros((0, 4), np.float32),
                                           converter=_boxes, metadata=_BOXES)
    labels: list[str] = field(factory=list, validator=is_str_list)
    scores: npt.NDArray[np.float32] = field(factory=lambda: np.zeros(0, np.float32),
                                            converter=_scores, metadata=wire("[float, ...]", as_list=True))
    image: ImageMsg | None = field(default=None, validator=instance_of(ImageMsg, optional=True))
    header: Header = header_field()
    #: The depth image the detections refer to (messages.md: "plus optional image and depth").
    depth: ImageMsg | None = field(default=None, validator=instance_of(ImageMsg, optional=True),
                                   metadata={"omit_when_none": True})

    def __attrs_post_init__(self) -> None:
        n = self.boxes.shape[0]
        if len(self.labels) != n or self.scores.shape[0] != n:
            raise TypeValidationError(
                f"detections: {n} boxes, {len(self.labels)} labels and {self.scores.shape[0]} scores must match"
            )


@named
@define(eq=False)
class TrackingsMsg(Message):
    """Tracked objects: 64-bit ``ids`` plus boxes, centroids and estimated velocities per object."""

    ids: npt.NDArray[np.int64] = field(factory=lambda: np.zeros(0, np.int64),
                                       converter=_ids, metadata=wire("[int, ...]", as_list=True))
    labels: list[str] = field(factory=list, validator=is_str_list)
    boxes: npt.NDArray[np.float32] = field(factory=lambda: np.zeros((0, 4), np.float32),
                                           converter=_boxes, metadata=_BOXES)
    centroids: npt.NDArray[np.float32] = field(factory=lambda: np.zeros((0, 2), np.float32),
                                               converter=_centroids, metadata=wire("[[x, y] float, ...]", as_list=True))
    estimated_velocities: npt.NDArray[np.float32] = field(
        factory=lambda: np.zeros((0, 2), np.float32),
        converter=_estimated_velocities, metadata=wire("[[vx, vy] float, ...]", as_list=True),
    )
    image: ImageMsg | None = field(default=None, validator=instance_of(ImageMsg, optional=True))
    header: Header = header_field()

    def __attrs_post_init__(self) -> None:
        n = self.ids.shape[0]
        sizes = {len(self.labels), self.boxes.shape[0], self.centroids.shape[0],
                 self.estimated_velocities.shape[0]}
        if sizes != {n}:
            raise TypeValidationError(f"trackings: ids, labels, boxes, centroids and velocities must all have {n} rows")


@named
@define(eq=False)
class PointsOfInterestMsg(Message):
    """Points on an image (Nx2 pixel coordinates), with the image they refer to."""

    points: npt.NDArray[np.float32] = field(factory=lambda: np.zeros((0, 2), np.float32),
                                            converter=_points, metadata=wire("[[x, y] float, ...]", as_list=True))
    image: ImageMsg | None = field(default=None, validator=instance_of(ImageMsg, optional=True))
    header: Header = header_field()
    #: The depth image the points refer to (messages.md: "plus the source image/depth").
    depth: ImageMsg | None = field(default=None, validator=instance_of(ImageMsg, optional=True),
                                   metadata={"omit_when_none": True})


class Detections(SupportedType):
    """Detection results (:class:`~agents_core.messages.DetectionsMsg`).

    Inputs get a :class:`~agents_core.callbacks.DetectionsCallback`: ``get_output()`` is one dict
    per object (``label``, ``score``, ``box``); ``callback.msg`` is the DetectionsMsg.
    """

    value_class = DetectionsMsg
    callback = DetectionsCallback

    @classmethod
    def example(cls) -> Any:
        return DetectionsMsg(boxes=[[1, 2, 30, 40], [5, 5, 9, 9]], labels=["cup", "person"],
                             scores=[0.9, 0.5], image=Image.example())


class _ListOf(SupportedType):
    """A list of one value class (the multi-source types)."""

    item: ClassVar[type[SupportedType]] = SupportedType
    value_class = list

    @classmethod
    def validate(cls, value: Any) -> Any:
        if not isinstance(value, list | tuple):
            raise TypeValidationError(f"{cls.type_name()} expects a list, got {type(value).__name__}")
        return [cls.item.validate(v) for v in value]

    @classmethod
    def example(cls) -> Any:
        return [cls.item.example(), cls.item.example()]


class DetectionsMultiSource(_ListOf):
    """Detections from several cameras: a list of DetectionsMsg."""

    item = Detections


class Trackings(SupportedType):
    """Tracked objects (:class:`~agents_core.messages.TrackingsMsg`)."""

    value_class = TrackingsMsg

    @classmethod
    def example(cls) -> Any:
        return TrackingsMsg(ids=[2**40 + 1], labels=["cup"], boxes=[[1, 2, 3, 4]], centroids=[[2, 3]],
                            estimated_velocities=[[0.1, -0.2]])


class TrackingsMultiSource(_ListOf):
    """Trackings from several cameras: a list of TrackingsMsg."""

    item = Trackings


class PointsOfInterest(SupportedType):
    """Points on an image (:class:`~agents_core.messages.PointsOfInterestMsg`)."""

    value_class = PointsOfInterestMsg

    @classmethod
    def example(cls) -> Any:
        return PointsOfInterestMsg(points=[[1.5, 2.5], [3, 4]], image=Image.example())
