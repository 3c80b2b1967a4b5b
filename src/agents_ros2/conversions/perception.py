"""ROS 2 conversions of perception results: ``agents_interfaces`` Detections2D, Trackings, their
multi-source bundles, and PointsOfInterest."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from agents_core import messages as m

from .base import RosConversion, ai, as_numpy, header_from_ros, header_to_ros, seq
from .media import optional_image_from_ros, optional_image_to_ros

__all__ = ["CONVERSIONS"]


def _boxes_to_ros(boxes: npt.NDArray[np.float32]) -> list[Any]:
    return [ai.Bbox2D(top_left_x=float(b[0]), top_left_y=float(b[1]), bottom_right_x=float(b[2]),
                      bottom_right_y=float(b[3])) for b in boxes]


def _boxes_from_ros(boxes: Sequence[Any]) -> npt.NDArray[np.float32]:
    return np.array([[b.top_left_x, b.top_left_y, b.bottom_right_x, b.bottom_right_y] for b in boxes],
                    dtype=np.float32).reshape(-1, 4)


def _points_to_ros(points: npt.NDArray[np.float32]) -> list[Any]:
    return [ai.Point2D(x=float(p[0]), y=float(p[1])) for p in points]


def _points_from_ros(points: Sequence[Any]) -> npt.NDArray[np.float32]:
    return np.array([[p.x, p.y] for p in points], dtype=np.float32).reshape(-1, 2)


def _detections_to_ros(v: m.DetectionsMsg) -> Any:
    out = ai.Detections2D(labels=list(v.labels), boxes=_boxes_to_ros(v.boxes))
    header_to_ros(v.header, out.header)
    out.scores = seq("f", v.scores, np.float32)
    optional_image_to_ros(v.image, out.image)
    _depth_to_ros(v.depth, out)
    return out


def _depth_to_ros(depth: m.ImageMsg | None, out: Any) -> None:
    # agents_interfaces built before the depth field was added has no such field: depth is not sent.
    if depth is not None and hasattr(out, "depth"):
        optional_image_to_ros(depth, out.depth)


def _depth_from_ros(msg: Any) -> m.ImageMsg | None:
    depth = getattr(msg, "depth", None)
    return None if depth is None else optional_image_from_ros(depth)


def _detections_from_ros(msg: Any) -> m.DetectionsMsg:
    return m.DetectionsMsg(boxes=_boxes_from_ros(msg.boxes), labels=list(msg.labels),
                           scores=as_numpy(msg.scores, np.float32), image=optional_image_from_ros(msg.image),
                           header=header_from_ros(msg.header), depth=_depth_from_ros(msg))


def _trackings_to_ros(v: m.TrackingsMsg) -> Any:
    out = ai.Trackings(labels=list(v.labels), boxes=_boxes_to_ros(v.boxes), centroids=_points_to_ros(v.centroids),
                       estimated_velocities=_points_to_ros(v.estimated_velocities))
    header_to_ros(v.header, out.header)
    out.ids = seq("q", v.ids, np.int64)
    optional_image_to_ros(v.image, out.image)
    return out


def _trackings_from_ros(msg: Any) -> m.TrackingsMsg:
    return m.TrackingsMsg(ids=as_numpy(msg.ids, np.int64), labels=list(msg.labels), boxes=_boxes_from_ros(msg.boxes),
                          centroids=_points_from_ros(msg.centroids),
                          estimated_velocities=_points_from_ros(msg.estimated_velocities),
                          image=optional_image_from_ros(msg.image), header=header_from_ros(msg.header))


def _multi_source(ros_type: type[Any], field_name: str, item_to: Callable[[Any], Any],
                  item_from: Callable[[Any], Any]) -> RosConversion:
    def to(values: list[Any]) -> Any:
        out = ros_type(**{field_name: [item_to(v) for v in values]})
        # The list itself has no header; stamp the bundle with its first item's.
        header_to_ros(values[0].header if values else m.Header(), out.header)
        return out

    def back(msg: Any) -> list[Any]:
        return [item_from(item) for item in getattr(msg, field_name)]

    return RosConversion(ros_type, to, back)


def _poi_to_ros(v: m.PointsOfInterestMsg) -> Any:
    out = ai.PointsOfInterest(points=_points_to_ros(v.points))
    header_to_ros(v.header, out.header)
    optional_image_to_ros(v.image, out.image)
    _depth_to_ros(v.depth, out)
    return out


def _poi_from_ros(msg: Any) -> m.PointsOfInterestMsg:
    return m.PointsOfInterestMsg(points=_points_from_ros(msg.points), image=optional_image_from_ros(msg.image),
                                 header=header_from_ros(msg.header), depth=_depth_from_ros(msg))


#: The built-in conversions of this family.
CONVERSIONS: dict[str, RosConversion] = {
    "Detections": RosConversion(ai.Detections2D, _detections_to_ros, _detections_from_ros),
    "DetectionsMultiSource": _multi_source(ai.Detections2DMultiSource, "detections", _detections_to_ros,
                                           _detections_from_ros),
    "Trackings": RosConversion(ai.Trackings, _trackings_to_ros, _trackings_from_ros),
    "TrackingsMultiSource": _multi_source(ai.TrackingsMultiSource, "trackings", _trackings_to_ros,
                                          _trackings_from_ros),
    "PointsOfInterest": RosConversion(ai.PointsOfInterest, _poi_to_ros, _poi_from_ros),
}
