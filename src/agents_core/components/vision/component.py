"""``Vision``: object detection and tracking on camera frames.

Each step takes the latest frame of every image input (Image, CompressedImage decoded with
Pillow, or the colour part of RGBD), asks the detector, and publishes:

- on Detections outputs, the detections of the frame that fired the step (the first camera's on
  a timer), and on DetectionsMultiSource outputs those of every camera, in input order;
- on Trackings / TrackingsMultiSource outputs, the tracked objects of ``labels_to_track`` (every
  label when None) with ids that persist across frames (int64), centroids and velocities in
  pixels per second (:class:`~agents_core.components.vision.tracking.ObjectTracker`, one per camera);
- with ``enable_visualization``, the frame with its boxes and labels drawn on the Image output.

Every message keeps its frame's header (stamp, frame_id); ``include_image`` also puts the frame in.
The detector is a remote :class:`~agents_core.models.VisionModel` through a RoboML client, or the
built-in :class:`~agents_core.engines.local_vision.LocalVisionModel` (``enable_local_model``).

A frame the detector cannot take (an encoding that has no RGB form, 16-bit pixels, an empty or an
oversized image, undecodable bytes) fails the step with :class:`~agents_core.errors.AlgorithmFailure`
(health ALGORITHM_FAILURE); the next good frame is processed as usual and the health recovers.
"""

from __future__ import annotations

import io
import re
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np
import numpy.typing as npt

from ... import supported_types as st
from ...actions import component_action
from ...clients.model_base import ModelClient
from ...errors import AlgorithmFailure, ConfigError, WiringError
from ...messages import CompressedImageMsg, DetectionsMsg, Header, ImageMsg, TrackingsMsg
from ...supported_types import (
    CompressedImage,
    Detections,
    DetectionsMultiSource,
    Image,
    SupportedType,
    Trackings,
    TrackingsMultiSource,
)
from ...topics import Topic
from ..component_base import TriggerType
from ..model_component import ModelComponent
from .config import VisionConfig
from .recording import MAX_FPS, MAX_RECORDING_S, confined_folder, record_frames, recording_path, write_gif
from .tracking import ObjectTracker

__all__ = ["Vision", "draw_detections", "frame_to_rgb"]

# RGBD is a subtype of Image: a depth camera's frame is accepted, and its colour image is what
# the detector sees (see frame_to_rgb).
_IMAGE_INPUTS: list[type[SupportedType]] = [Image, CompressedImage, st.RGBD]
_RESULT_OUTPUTS: list[type[SupportedType]] = [Detections, DetectionsMultiSource, Trackings, TrackingsMultiSource]

# Box colours of the visualization, cycled by class.
_PALETTE = np.array([[230, 25, 75], [60, 180, 75], [255, 225, 25], [0, 130, 200], [245, 130, 48],
                     [145, 30, 180], [70, 240, 240], [240, 50, 230]], np.uint8)


def _decode(msg: CompressedImageMsg) -> ImageMsg:
    try:
        from PIL import Image as PILImage  # noqa: PLC0415  (optional: only CompressedImage inputs need it)
    except ImportError as exc:
        raise AlgorithmFailure("decoding a CompressedImage needs Pillow: pip install pillow "
                               "(or publish raw Image frames)") from exc
    try:
        with PILImage.open(io.BytesIO(msg.data)) as img:
            pixels = np.asarray(img.convert("RGB"))
    except Exception as exc:  # Pillow raises many types for bad data
        raise AlgorithmFailure(f"cannot decode the {msg.format!r} CompressedImage ({len(msg.data)} bytes): "
                               f"{type(exc).__name__}: {exc}") from exc
    return ImageMsg(data=pixels, encoding="rgb8", header=msg.header)


def _colour_part(value: Any) -> Any:
    for name in ("rgb", "image", "color", "colour"):
        part = getattr(value, name, None)
        if isinstance(part, ImageMsg | CompressedImageMsg):
            # The frame's own header (an RGBD's stamp and frame) is the one the outputs keep.
            header = getattr(value, "header", None)
            return attrs.evolve(part, header=header) if isinstance(header, Header) else part
    raise AlgorithmFailure(f"cannot find the colour image in a {type(value).__name__}")


def frame_to_rgb(value: Any, max_side: int) -> tuple[ImageMsg, npt.NDArray[np.uint8]]:
    """The frame as an ImageMsg (decoded if compressed) and its RGB uint8 pixels, or AlgorithmFailure.

    bgr8, bgra8, rgba8 and mono8 are converted; other encodings (16-bit mono, depth) are refused.
    """
    if not isinstance(value, ImageMsg | CompressedImageMsg):
        value = _colour_part(value)
    image = _decode(value) if isinstance(value, CompressedImageMsg) else value
    if image.height == 0 or image.width == 0:
        raise AlgorithmFailure(f"the frame is empty ({image.height}x{image.width})")
    if max(image.height, image.width) > max_side:
        raise AlgorithmFailure(f"a {image.height}x{image.width} frame is larger than max_image_side ({max_side}); "
                               "downscale it, or raise config.max_image_side")
    if image.data.dtype != np.uint8:
        raise AlgorithmFailure(f"the detector takes 8-bit colour or grey frames; got {image.encoding!r} "
                               f"({image.data.dtype})")
    pixels = image.to_rgb()
    if pixels.shape[2] == 1:
        pixels = np.repeat(pixels, 3, axis=2)
    return image, np.ascontiguousarray(pixels)


def draw_detections(pixels: npt.NDArray[np.uint8], boxes: npt.NDArray[Any], labels: Sequence[str],
                    scores: npt.NDArray[Any] | None = None, ids: Sequence[int] | None = None) -> npt.NDArray[np.uint8]:
    """A copy of ``pixels`` (RGB) with each box drawn and labelled (labels need Pillow; boxes do not)."""
    out = np.array(pixels, np.uint8, copy=True)
    height, width = out.shape[:2]
    names = sorted(set(labels))
    thickness = max(2, round(min(height, width) / 200))
    captions = []
    for n, (box, label) in enumerate(zip(np.asarray(boxes).reshape(-1, 4), labels, strict=True)):
        colour = _PALETTE[names.index(label) % len(_PALETTE)]
        x1, y1, x2, y2 = (round(float(v)) for v in box)
        x1, x2 = sorted((min(max(x1, 0), width - 1), min(max(x2, 0), width - 1)))
        y1, y2 = sorted((min(max(y1, 0), height - 1), min(max(y2, 0), height - 1)))
        t = thickness
        out[y1:y1 + t, x1:x2 + 1] = colour
        out[max(y2 - t + 1, 0):y2 + 1, x1:x2 + 1] = colour
        out[y1:y2 + 1, x1:x1 + t] = colour
        out[y1:y2 + 1, max(x2 - t + 1, 0):x2 + 1] = colour
        caption = label if ids is None else f"#{ids[n]} {label}"
        if scores is not None:
            caption += f" {float(scores[n]):.2f}"
        captions.append((x1, y1, caption, tuple(int(c) for c in colour)))
    try:
        from PIL import Image as PILImage  # noqa: PLC0415
        from PIL import ImageDraw  # noqa: PLC0415
    except ImportError:
        return out  # boxes only
    canvas = PILImage.fromarray(out)
    draw = ImageDraw.Draw(canvas)
    for x, y, caption, colour in captions:
        left, top, right, bottom = draw.textbbox((x, y), caption)
        lift = bottom - top + 4
        ty = y - lift if y >= lift else y
        draw.rectangle((x, ty, x + right - left + 4, ty + lift), fill=colour)
        draw.text((x + 2, ty + 1), caption, fill=(0, 0, 0))
    return np.asarray(canvas)


class Vision(ModelComponent):
    """Detects (and tracks) objects in camera frames (see the module docs).

    :param inputs: Image / CompressedImage / RGBD topics, one per camera.
    :param outputs: Detections, DetectionsMultiSource, Trackings and/or TrackingsMultiSource topics,
        plus an Image topic for the annotated frames when ``enable_visualization`` is on.
    :param model_client: a client serving a :class:`~agents_core.models.VisionModel` (RoboML);
        None with ``config.enable_local_model``.
    :param config: a :class:`~agents_core.config.VisionConfig`.
    :param trigger: default: every image input (each new frame fires a step).
    """

    config_class = VisionConfig
    handled_outputs: Sequence[type[SupportedType]] = (*_RESULT_OUTPUTS, Image)

    def __init__(
        self,
        inputs: Sequence[Topic] | None = None,
        outputs: Sequence[Topic] | None = None,
        model_client: ModelClient | None = None,
        config: VisionConfig | None = None,
        trigger: TriggerType | None = None,
        component_name: str = "vision",
        **kwargs: Any,
    ) -> None:
        self.allowed_inputs = {"Required": [_IMAGE_INPUTS]}
        self.allowed_outputs = {"Required": [_RESULT_OUTPUTS], "Optional": [Image]}
        if trigger is None and inputs:
            trigger = list(inputs)
        super().__init__(inputs=inputs, outputs=outputs, model_client=model_client, config=config, trigger=trigger,
                         component_name=component_name, **kwargs)
        self.config: VisionConfig
        has_image_output = any(issubclass(t.msg_type, Image) for t in self.outputs)
        if self.config.enable_visualization and not has_image_output:
            raise WiringError(f"component {self.component_name!r}: enable_visualization needs an Image output")
        if has_image_output and not self.config.enable_visualization:
            raise WiringError(f"component {self.component_name!r}: an Image output carries the annotated frames; "
                              "set config.enable_visualization=True")
        self._sources = [t for t in self.inputs if any(issubclass(t.msg_type, k) for k in _IMAGE_INPUTS)]
        self._trackers = [self._new_tracker() for _ in self._sources]
        #: Frames processed and frames refused since the component was created.
        self.frames_processed = 0
        self.frames_refused = 0
        # Set at shutdown: background recordings end there and write what they have.
        self._recordings_stop = threading.Event()
        self._recordings_lock = threading.Lock()
        self._recordings_running = 0
        # Per camera: (arrivals, latest frame), for record_video. A callback's ``msg`` is pinned to
        # the frame being detected while a step runs, so a recording sampling it would repeat that one.
        self._arrivals_lock = threading.Lock()
        self._arrivals: dict[str, tuple[int, Any]] = {}
        callbacks = {**self.callbacks, **self.trig_callbacks}
        for source in self._sources:
            callbacks[source.name].on_callback_execute(self._arrival_hook(source.name))

    def _new_tracker(self) -> ObjectTracker:
        return ObjectTracker(max_age=self.config.tracking_max_age, iou_threshold=self.config.tracking_iou_threshold)

    # -- model --------------------------------------------------------------------------------

    def _deploy_local_model(self) -> None:
        from ...engines.local_vision import LocalVisionModel  # noqa: PLC0415  (onnxruntime is optional)

        cfg = self.config
        self.local_model = LocalVisionModel(
            model_path=cfg.local_model_path, device=cfg.device_local_model, ncpu=cfg.ncpu_local_model,
            threshold=cfg.threshold, nms_iou=cfg.nms_threshold, labels=cfg.dataset_labels,
            labels_path=cfg.dataset_labels_file, input_height=cfg.input_height, input_width=cfg.input_width)

    def _arrival_hook(self, name: str) -> Any:
        def note(value: Any) -> None:
            with self._arrivals_lock:
                self._arrivals[name] = (self._arrivals.get(name, (0, None))[0] + 1, value)

        return note

    def _latest_arrival(self, name: str) -> tuple[int, Any]:
        with self._arrivals_lock:
            return self._arrivals.get(name, (0, None))

    def custom_on_shutdown(self) -> None:
        self._recordings_stop.set()
        super().custom_on_shutdown()

    def _warmup(self, *args: Any, **kwargs: Any) -> None:
        self._call_inference({"images": [np.zeros((64, 64, 3), np.uint8)], **self.inference_params})

    def _create_input(self, *args: Any, **kwargs: Any) -> dict[str, Any] | None:
        images = kwargs.get("images") or []
        return {"images": list(images), **self.inference_params} if images else None

    # -- the step -----------------------------------------------------------------------------

    def _latest(self, topic: Topic | None = None) -> list[tuple[int, Any]]:
        """(source index, latest frame) of the cameras this step looks at: every camera when a
        MultiSource output wants them all, else the one that fired the step (on a timer, the first)."""
        callbacks = {**self.callbacks, **self.trig_callbacks}
        latest = [(i, callbacks[t.name].msg) for i, t in enumerate(self._sources) if callbacks[t.name].msg is not None]
        if any(issubclass(t.msg_type, DetectionsMultiSource | TrackingsMultiSource) for t in self.outputs):
            return latest
        # Only the firing camera: another camera's stale (or bad) frame must not hold this one up.
        firing = [(i, v) for i, v in latest if topic is not None and self._sources[i].name == topic.name]
        return firing or latest[:1]

    def _execution_step(self, **kwargs: Any) -> None:
        topic = kwargs.get("topic")
        latest = self._latest(topic)
        if not latest:
            return
        firing = next((i for i, _ in latest if topic is not None and self._sources[i].name == topic.name),
                      latest[0][0])
        frames: list[tuple[int, ImageMsg, npt.NDArray[np.uint8]]] = []
        for index, value in latest:
            try:
                image, pixels = frame_to_rgb(value, self.config.max_image_side)
            except AlgorithmFailure as exc:
                self.frames_refused += 1
                raise AlgorithmFailure(f"component {self.component_name!r}: input "
                                       f"{self._sources[index].name!r}: {exc}") from exc
            frames.append((index, image, pixels))
        inference_input = self._create_input(images=[p for _, _, p in frames])
        if inference_input is None:
            return
        result = self._call_inference(inference_input)
        per_image = result["output"]
        if not isinstance(per_image, list) or len(per_image) != len(frames):
            raise AlgorithmFailure(f"component {self.component_name!r}: the detector answered "
                                   f"{type(per_image).__name__} for {len(frames)} image(s)")
        detections = [self._to_detections(found, image) for (_, image, _), found in zip(frames, per_image,
                                                                                       strict=True)]
        self.frames_processed += len(frames)
        self._publish_results(frames, detections, firing)

    def _to_detections(self, found: Any, image: ImageMsg) -> DetectionsMsg:
        try:
            boxes = np.asarray(found.get("bboxes", []), np.float32).reshape(-1, 4)
            labels = [str(label) for label in found.get("labels", [])]
            scores = np.asarray(found.get("scores", []), np.float32).reshape(-1)
            # A remote model filters by its own threshold; the component's applies to both alike.
            keep = scores >= self.config.threshold
            return DetectionsMsg(boxes=boxes[keep], labels=[lb for lb, k in zip(labels, keep, strict=True) if k],
                                 scores=scores[keep], image=image if self.config.include_image else None,
                                 header=image.header)
        except (AttributeError, TypeError, ValueError) as exc:
            raise AlgorithmFailure(f"component {self.component_name!r}: unusable detector answer "
                                   f"{found!r:.200}: {exc}") from exc

    def _track(self, index: int, det: DetectionsMsg, image: ImageMsg) -> TrackingsMsg:
        wanted = self.config.labels_to_track
        keep = [i for i, label in enumerate(det.labels) if wanted is None or label in wanted]
        objects = self._trackers[index].update(det.boxes[keep], [det.labels[i] for i in keep],
                                               stamp=image.header.stamp, scores=det.scores[keep])
        return TrackingsMsg(
            ids=np.array([o.id for o in objects], np.int64), labels=[o.label for o in objects],
            boxes=np.array([o.box for o in objects], np.float32).reshape(-1, 4),
            centroids=np.array([o.centroid for o in objects], np.float32).reshape(-1, 2),
            estimated_velocities=np.array([o.velocity for o in objects], np.float32).reshape(-1, 2),
            image=image if self.config.include_image else None, header=image.header)

    def _publish_results(self, frames: list[tuple[int, ImageMsg, npt.NDArray[np.uint8]]],
                         detections: list[DetectionsMsg], firing: int) -> None:
        pubs = list(self.publishers_dict.values())
        wants_tracks = any(issubclass(p.topic.msg_type, Trackings | TrackingsMultiSource) for p in pubs)
        trackings = [self._track(index, det, image) for (index, image, _), det in zip(frames, detections,
                                                                                       strict=True)] \
            if wants_tracks else []
        at = next((n for n, (index, _, _) in enumerate(frames) if index == firing), 0)
        for pub in pubs:
            kind = pub.topic.msg_type
            if issubclass(kind, DetectionsMultiSource):
                pub.publish(detections)
            elif issubclass(kind, Detections):
                pub.publish(detections[at])
            elif issubclass(kind, TrackingsMultiSource):
                pub.publish(trackings)
            elif issubclass(kind, Trackings):
                pub.publish(trackings[at])
            elif issubclass(kind, Image):
                _, image, pixels = frames[at]
                det = detections[at]
                drawn = draw_detections(pixels, det.boxes, det.labels, det.scores)
                pub.publish(ImageMsg(data=drawn, encoding="rgb8", header=Header(image.header.stamp_ns,
                                                                                image.header.frame_id)))

    # -- actions ------------------------------------------------------------------------------

    @component_action(description={
        "description": "Start tracking objects with this label (tracking follows only that label from now on).",
        "parameters": {"type": "object",
                       "properties": {"label": {"type": "string", "description": "the class name, e.g. 'person'"}},
                       "required": ["label"]},
    })
    def track(self, label: str) -> bool:
        """Track objects labelled ``label`` only, with fresh ids (sets ``labels_to_track`` to ``[label]``)."""
        if not isinstance(label, str) or not label.strip():
            raise AlgorithmFailure(f"component {self.component_name!r}: track() needs a label, got {label!r}")
        self.config.labels_to_track = [label.strip()]
        for tracker in self._trackers:
            tracker.reset()
        self._logger.info("now tracking %r", label)
        return True

    @component_action(description={
        "description": "Detect objects in the camera's latest frame now and say what was seen.",
        "parameters": {"type": "object", "properties": {
            "topic_name": {"type": "string", "description": "the camera topic (optional: the first camera)"},
            "save_path": {"type": "string", "description": "a folder to save the picture in (optional)"}},
            "required": []},
    })
    def take_picture(self, topic_name: str | None = None, save_path: str | None = None,
                     timeout: float = 0.5) -> dict[str, Any]:
        """Detect objects in the latest frame of each camera now; publishes as a step would and returns
        ``{"detections": [{"source", "labels", "scores", "boxes", "stamp"}, ...]}``.

        Upstream's form ``take_picture(topic_name, save_path)``: only that camera (waiting up to
        ``timeout`` seconds for a frame), and with ``save_path`` the frame is also saved there as a
        PNG file (Pillow), whose path the answer gives as ``"path"``.
        """
        index_of = {t.name: i for i, t in enumerate(self._sources)}
        if topic_name is not None and topic_name not in index_of:
            raise WiringError(f"component {self.component_name!r}: {topic_name!r} is not one of its cameras "
                              f"{sorted(index_of)}")
        deadline = time.monotonic() + (timeout if topic_name is not None else 0.0)
        while True:
            latest = self._latest()
            if topic_name is not None:
                callbacks = {**self.callbacks, **self.trig_callbacks}
                msg = callbacks[topic_name].msg
                latest = [(index_of[topic_name], msg)] if msg is not None else []
            if latest or time.monotonic() >= deadline:
                break
            time.sleep(0.02)
        if not latest:
            raise AlgorithmFailure(f"component {self.component_name!r}: no frame has arrived yet")
        frames = [(index, *frame_to_rgb(value, self.config.max_image_side)) for index, value in latest]
        result = self._call_inference({"images": [p for _, _, p in frames], **self.inference_params})
        detections = [self._to_detections(found, image) for (_, image, _), found in zip(frames, result["output"],
                                                                                       strict=True)]
        self._publish_results(frames, detections, frames[0][0])
        answer: dict[str, Any] = {
            "detections": [{"source": self._sources[index].name, "labels": list(det.labels),
                            "scores": [round(float(s), 4) for s in det.scores],
                            "boxes": det.boxes.round(1).tolist(), "stamp": image.header.stamp}
                           for (index, image, _), det in zip(frames, detections, strict=True)]}
        if save_path is not None:
            folder = confined_folder(self.config.recordings_dir, save_path,
                                     f"component {self.component_name!r}: take_picture")
            answer["path"] = _save_picture(frames[0][2], self._sources[frames[0][0]].name, folder)
        return answer

    @component_action(description={
        "description": "Record a video from a camera for some seconds (saved as an animated GIF).",
        "parameters": {"type": "object", "properties": {
            "topic_name": {"type": "string", "description": "the camera topic (optional: the first camera)"},
            "duration": {"type": "number", "description": "seconds to record (default 5)"},
            "save_path": {"type": "string", "description": "the folder to save the video in (optional)"}},
            "required": []},
    })
    def record_video(self, topic_name: str | None = None, duration: float = 5.0, save_path: str | None = None,
                     fps: int = 30, wait: bool = False) -> str:
        """Record ``duration`` seconds of camera ``topic_name`` (None: the first camera) at up to ``fps``
        frames per second into an animated GIF in ``save_path``; returns the file's path.

        ``save_path`` (default: ``config.recordings_dir``) must lie inside ``config.recordings_dir``;
        at most ``config.max_recordings`` recordings run at once, and one more is refused with
        :class:`~agents_core.errors.AlgorithmFailure` (each keeps at most ``config.max_recording_bytes``).

        As upstream, the recording runs in a background thread and the call returns at once; the
        file appears at the returned path, complete, when the recording ends (if no frame arrived
        nothing is written and a warning says so). ``wait=True`` returns once the file is written
        and raises :class:`~agents_core.errors.AlgorithmFailure` if no frame arrived. Detection goes
        on while recording (upstream pauses it when the camera is the trigger). Needs Pillow.
        """
        index_of = {t.name: i for i, t in enumerate(self._sources)}
        name = topic_name if topic_name is not None else self._sources[0].name
        if name not in index_of:
            raise WiringError(f"component {self.component_name!r}: {name!r} is not one of its cameras "
                              f"{sorted(index_of)}")
        if isinstance(duration, bool) or not isinstance(duration, int | float) or not 0 < duration <= MAX_RECORDING_S:
            raise ConfigError(f"record_video: duration must be in (0, {MAX_RECORDING_S:.0f}] seconds, got {duration!r}")
        if isinstance(fps, bool) or not isinstance(fps, int) or not 1 <= fps <= MAX_FPS:
            raise ConfigError(f"record_video: fps must be an int in [1, {MAX_FPS}], got {fps!r}")
        what = f"component {self.component_name!r}: record_video"
        path = recording_path(confined_folder(self.config.recordings_dir, save_path, what), name)
        max_side, max_bytes = self.config.max_image_side, self.config.max_recording_bytes
        with self._recordings_lock:
            if self._recordings_running >= self.config.max_recordings:
                raise AlgorithmFailure(f"{what}: {self._recordings_running} recordings are running, the most "
                                       f"allowed at once (config.max_recordings={self.config.max_recordings}); "
                                       "try again when one ends")
            self._recordings_running += 1

        def record() -> str:
            try:
                frames, cut = record_frames(lambda: self._latest_arrival(name),
                                            lambda value: frame_to_rgb(value, max_side)[1],
                                            float(duration), fps, stop=self._recordings_stop.is_set,
                                            max_bytes=max_bytes)
            finally:
                with self._recordings_lock:
                    self._recordings_running -= 1
            end = time.monotonic()
            if cut:
                self._logger.warning("recording of %r ended early: %s", name, cut)
            if not frames:
                raise AlgorithmFailure(f"component {self.component_name!r}: no frame arrived on {name!r} in "
                                       f"{duration} s; nothing recorded")
            write_gif(frames, path, fps, end)
            self._logger.info("saved %d frames from %r to %s", len(frames), name, path)
            return str(path)

        if wait:
            return record()

        def record_in_background() -> None:
            try:
                record()
            except Exception as exc:  # a background thread has no caller to raise to
                self._logger.warning("record_video on %r: %s", name, exc)

        try:
            threading.Thread(target=record_in_background, name=f"{self.component_name}-record-{name}",
                             daemon=True).start()
        except BaseException:
            with self._recordings_lock:
                self._recordings_running -= 1
            raise
        self._logger.info("recording %r for %s s into %s", name, duration, path)
        return str(path)


def _save_picture(pixels: npt.NDArray[np.uint8], source: str, folder: str) -> str:
    """Save an RGB frame as ``<folder>/<source>_<time>.png``; returns the file's path."""
    try:
        from PIL import Image as PILImage  # noqa: PLC0415  (optional: only saving pictures needs it)
    except ImportError as exc:
        raise AlgorithmFailure("saving a picture needs Pillow: pip install pillow") from exc
    directory = Path(folder).expanduser()
    directory.mkdir(parents=True, exist_ok=True)
    stem = re.sub(r"[^A-Za-z0-9_.-]", "_", source)
    path = directory / f"{stem}_{time.strftime('%Y%m%d_%H%M%S')}_{time.time_ns() % 10**9:09d}.png"
    PILImage.fromarray(np.ascontiguousarray(pixels)).save(path)
    return str(path)
