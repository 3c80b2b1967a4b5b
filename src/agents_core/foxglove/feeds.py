"""How each of our message types appears in Foxglove: the channels a topic gets and what a value becomes.

One :class:`TopicFeed` per served topic owns its Foxglove channels (created at once, so a client
sees them advertised before the first value) and turns each value into Foxglove's well-known
schemas:

==========================================  =====================================================
our type                                    Foxglove channel(s) (topic ``/name``)
==========================================  =====================================================
Image (and RGBD: its colour image)          ``/name``: ``foxglove.RawImage``
CompressedImage                             ``/name``: ``foxglove.CompressedImage``
Detections, Trackings, PointsOfInterest     ``/name``: ``foxglove.ImageAnnotations`` (a box and
                                            label per object), and ``/name/image``: the image
                                            they were found on, when the value carries it; both
                                            stamped with that image's stamp, so Foxglove's Image
                                            panel draws the boxes on their frame
Odometry                                    ``/name``: ``foxglove.PoseInFrame`` and
                                            ``/name/transform``: ``foxglove.FrameTransform``
                                            (frame_id -> child_frame_id)
Pose, PoseStamped                           ``/name``: ``foxglove.PoseInFrame``
Path, PoseArray                             ``/name``: ``foxglove.PosesInFrame``
String, StreamingString (whole replies)     ``/name``: ``foxglove.Log`` (info)
ComponentStatus (``<component>/status``)    ``/name``: ``foxglove.Log``, its level from the health
anything else                               ``/name``: JSON (large arrays and bytes summarised)
==========================================  =====================================================

Messages are stamped with the value's header stamp (the time it was produced), or the time of
arrival when the value has none.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from foxglove import Channel, Context
from foxglove import channels as fc
from foxglove import messages as fm

from ..messages import (
    CompressedImageMsg,
    DetectionsMsg,
    ImageMsg,
    OdometryMsg,
    PathMsg,
    PointsOfInterestMsg,
    PoseArrayMsg,
    PoseMsg,
    RGBDMsg,
    StreamingStringMsg,
    TrackingsMsg,
)
from ..topics import Topic
from ..types.base import SupportedType
from ..types.component_status import ComponentStatus, ComponentStatusMsg
from ..types.geometry import Odometry, Path, Pose, PoseArray
from ..types.media import CompressedImage, Image
from ..types.perception import Detections, PointsOfInterest, Trackings
from ..types.summary import summarize
from ..types.text import StreamingString, String

__all__ = ["TopicFeed", "feed_kind"]

#: Log levels of the component health names (agents_core.status.HealthStatus).
_HEALTH_LEVELS = {"HEALTHY": fm.LogLevel.Info, "ALGORITHM_FAILURE": fm.LogLevel.Warning,
                  "COMPONENT_FAILURE": fm.LogLevel.Error, "SYSTEM_FAILURE": fm.LogLevel.Fatal}
_BOX_COLOR = fm.Color(r=0.1, g=0.9, b=0.2, a=1.0)
_TEXT_COLOR = fm.Color(r=1.0, g=1.0, b=1.0, a=1.0)
_TEXT_BACKGROUND = fm.Color(r=0.0, g=0.0, b=0.0, a=0.6)

# Checked in order: a subclass (PoseStamped, RGBD, StreamingString) before its parent's entry.
_KINDS: tuple[tuple[type[SupportedType], str], ...] = (
    (Image, "image"), (CompressedImage, "compressed_image"),
    (Detections, "annotations"), (Trackings, "annotations"), (PointsOfInterest, "annotations"),
    (Odometry, "odometry"), (Pose, "pose"), (Path, "poses"), (PoseArray, "poses"),
    (StreamingString, "stream_text"), (String, "text"), (ComponentStatus, "status"),
)


def feed_kind(msg_type: type[SupportedType]) -> str:
    """How values of ``msg_type`` are shown: ``"image"``, ``"annotations"``, ..., else ``"json"``."""
    for our_type, kind in _KINDS:
        if issubclass(msg_type, our_type):
            return kind
    return "json"


def _stamp_ns(value: Any) -> int:
    header = getattr(value, "header", None)
    stamp = getattr(header, "stamp_ns", 0)
    return int(stamp) if stamp else time.time_ns()


def _timestamp(stamp_ns: int) -> fm.Timestamp:
    return fm.Timestamp(stamp_ns // 1_000_000_000, stamp_ns % 1_000_000_000)


def _frame_id(value: Any, default: str) -> str:
    return str(getattr(getattr(value, "header", None), "frame_id", "") or default)


def raw_image(image: ImageMsg, stamp_ns: int) -> fm.RawImage:
    """Our HxWxC image as ``foxglove.RawImage`` (the encodings have the same names in both)."""
    data = np.ascontiguousarray(image.data)
    if data.dtype.byteorder == ">":  # Foxglove reads multi-byte pixels as little-endian
        data = data.astype(data.dtype.newbyteorder("<"))
    return fm.RawImage(timestamp=_timestamp(stamp_ns), frame_id=_frame_id(image, "camera"), width=image.width,
                       height=image.height, encoding=image.encoding, step=int(data.strides[0]), data=data.tobytes())


def _pose(pose: PoseMsg) -> fm.Pose:
    x, y, z = (float(v) for v in pose.position)
    qx, qy, qz, qw = (float(v) for v in pose.orientation)
    return fm.Pose(position=fm.Vector3(x=x, y=y, z=z), orientation=fm.Quaternion(x=qx, y=qy, z=qz, w=qw))


def image_annotations(value: DetectionsMsg | TrackingsMsg | PointsOfInterestMsg, stamp_ns: int) -> fm.ImageAnnotations:
    """Boxes (closed outlines) with a label each, or points, on the image of ``stamp_ns``."""
    ts = _timestamp(stamp_ns)
    if isinstance(value, PointsOfInterestMsg):
        points = [fm.Point2(x=float(x), y=float(y)) for x, y in value.points]
        return fm.ImageAnnotations(points=[fm.PointsAnnotation(
            timestamp=ts, type=fm.PointsAnnotationType.Points, points=points, outline_color=_BOX_COLOR,
            thickness=4.0)])
    outlines, texts = [], []
    for i, (x1, y1, x2, y2) in enumerate(value.boxes.tolist()):
        corners = [fm.Point2(x=x1, y=y1), fm.Point2(x=x2, y=y1), fm.Point2(x=x2, y=y2), fm.Point2(x=x1, y=y2)]
        outlines.append(fm.PointsAnnotation(timestamp=ts, type=fm.PointsAnnotationType.LineLoop, points=corners,
                                            outline_color=_BOX_COLOR, thickness=2.0))
        if isinstance(value, DetectionsMsg):
            label = f"{value.labels[i]} {float(value.scores[i]):.2f}"
        else:
            label = f"{value.labels[i]} #{int(value.ids[i])}"
        texts.append(fm.TextAnnotation(timestamp=ts, position=fm.Point2(x=x1, y=y1), text=label, font_size=14.0,
                                       text_color=_TEXT_COLOR, background_color=_TEXT_BACKGROUND))
    return fm.ImageAnnotations(points=outlines, texts=texts)


class TopicFeed:
    """The Foxglove channels of one of our topics, and the conversion of its values.

    :param topic: our topic; its Foxglove topic is ``"/" + topic.name``.
    :param context: the bridge's Foxglove context (its channels reach only that bridge's server).
    :param max_text_chars: the longest text sent in a Log message.
    """

    def __init__(self, topic: Topic, context: Context, max_text_chars: int) -> None:
        self.topic = topic
        self.kind = feed_kind(topic.msg_type)
        self.name = "/" + topic.name.lstrip("/")
        self._max_text = max_text_chars
        self._stream: list[str] = []
        self._stream_chars = 0
        metadata = {"agents_core_type": topic.msg_type.type_name()}
        make = {"image": fc.RawImageChannel, "compressed_image": fc.CompressedImageChannel,
                "annotations": fc.ImageAnnotationsChannel, "odometry": fc.PoseInFrameChannel,
                "pose": fc.PoseInFrameChannel, "poses": fc.PosesInFrameChannel, "stream_text": fc.LogChannel,
                "text": fc.LogChannel, "status": fc.LogChannel}.get(self.kind)
        self._main: Any = (make(self.name, metadata=metadata, context=context) if make is not None
                           else Channel(self.name, context=context, metadata=metadata))
        self._extra: Any = None
        if self.kind == "annotations":
            self._extra = fc.RawImageChannel(self.name + "/image", metadata=metadata, context=context)
        elif self.kind == "odometry":
            self._extra = fc.FrameTransformChannel(self.name + "/transform", metadata=metadata, context=context)

    def channel_topics(self) -> list[str]:
        """The Foxglove topics this feed advertises."""
        return [self._main.topic()] + ([self._extra.topic()] if self._extra is not None else [])

    def close(self) -> None:
        """Withdraw the channels (clients see them unadvertised)."""
        self._main.close()
        if self._extra is not None:
            self._extra.close()

    def show(self, value: Any) -> None:
        """Convert ``value`` and log it on the feed's channels."""
        getattr(self, "_show_" + self.kind)(value)

    def _text(self, text: str) -> str:
        return text if len(text) <= self._max_text else text[: self._max_text] + f"... ({len(text)} chars)"

    def _log(self, text: str, stamp_ns: int, level: Any = fm.LogLevel.Info, name: str = "") -> None:
        self._main.log(fm.Log(timestamp=_timestamp(stamp_ns), level=level, message=self._text(text),
                              name=name or self.topic.name), log_time=stamp_ns)

    def _show_image(self, value: ImageMsg | RGBDMsg) -> None:
        image = value.image if isinstance(value, RGBDMsg) else value
        stamp = _stamp_ns(value)
        self._main.log(raw_image(image, stamp), log_time=stamp)

    def _show_compressed_image(self, value: CompressedImageMsg) -> None:
        stamp = _stamp_ns(value)
        self._main.log(fm.CompressedImage(timestamp=_timestamp(stamp), frame_id=_frame_id(value, "camera"),
                                          data=bytes(value.data), format=value.format), log_time=stamp)

    def _show_annotations(self, value: DetectionsMsg | TrackingsMsg | PointsOfInterestMsg) -> None:
        # On the image's timeline: stamped like the frame the objects were found on.
        stamp = _stamp_ns(value.image) if value.image is not None else _stamp_ns(value)
        if value.image is not None:
            self._extra.log(raw_image(value.image, stamp), log_time=stamp)
        self._main.log(image_annotations(value, stamp), log_time=stamp)

    def _show_pose(self, value: PoseMsg) -> None:
        stamp = _stamp_ns(value)
        self._main.log(fm.PoseInFrame(timestamp=_timestamp(stamp), frame_id=_frame_id(value, "map"),
                                      pose=_pose(value)), log_time=stamp)

    def _show_odometry(self, value: OdometryMsg) -> None:
        stamp = _stamp_ns(value)
        parent = _frame_id(value, "odom")
        self._main.log(fm.PoseInFrame(timestamp=_timestamp(stamp), frame_id=parent, pose=_pose(value.pose)),
                       log_time=stamp)
        qx, qy, qz, qw = (float(v) for v in value.pose.orientation)
        self._extra.log(fm.FrameTransform(timestamp=_timestamp(stamp), parent_frame_id=parent,
                                          child_frame_id=value.child_frame_id or "base_link",
                                          translation=fm.Vector3(x=float(value.pose.position[0]),
                                                                 y=float(value.pose.position[1]),
                                                                 z=float(value.pose.position[2])),
                                          rotation=fm.Quaternion(x=qx, y=qy, z=qz, w=qw)), log_time=stamp)

    def _show_poses(self, value: PathMsg | PoseArrayMsg) -> None:
        stamp = _stamp_ns(value)
        self._main.log(fm.PosesInFrame(timestamp=_timestamp(stamp), frame_id=_frame_id(value, "map"),
                                       poses=[_pose(p) for p in value.poses]), log_time=stamp)

    def _show_text(self, value: str) -> None:
        self._log(value, time.time_ns())

    def _show_stream_text(self, value: StreamingStringMsg) -> None:
        # A streamed reply arrives in chunks: one Log line per whole reply, bounded in size.
        if not value.stream:
            self._log(value.data, _stamp_ns(value))
            return
        if self._stream_chars <= self._max_text:
            self._stream.append(value.data)
            self._stream_chars += len(value.data)
        if value.done:
            text, self._stream, self._stream_chars = "".join(self._stream), [], 0
            self._log(text, _stamp_ns(value))

    def _show_status(self, value: ComponentStatusMsg) -> None:
        text = f"{value.lifecycle_state} {value.health}" + (f": {value.message}" if value.message else "")
        self._log(text, _stamp_ns(value), _HEALTH_LEVELS.get(value.health, fm.LogLevel.Unknown), value.component)

    def _show_json(self, value: Any) -> None:
        doc = summarize(value)
        self._main.log(doc if isinstance(doc, dict) else {"value": doc}, log_time=_stamp_ns(value))
