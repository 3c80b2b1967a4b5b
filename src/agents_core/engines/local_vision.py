"""The built-in local object detector on ONNX Runtime: :class:`LocalVisionModel`.

It recognises the common detector export signatures by the model's inputs and outputs, and does
the pre- and post-processing each one needs:

=============  =====================================================  ===========================================
signature      inputs -> outputs                                      post-processing here
=============  =====================================================  ===========================================
``ssd``        uint8 ``[1,H,W,3]`` -> scores ``[1,N,C]``,              per-box best class, threshold, NMS;
               boxes ``[1,N,1,4]`` (TF Object Detection API / SSD)    boxes ``ymin,xmin,ymax,xmax`` in 0..1
``tf_od``      uint8 ``[1,H,W,3]`` -> ``detection_boxes``,             threshold (the graph already did NMS)
               ``detection_scores``, ``detection_classes``
``deim``       float ``images[N,3,H,W]`` + int64                        threshold (boxes come in image pixels)
               ``orig_target_sizes[N,2]`` -> labels, boxes, scores
               (DEIM / D-FINE / RT-DETR exports)
``yolo``       float ``[1,3,H,W]`` -> ``[1,4+C,N]`` (Ultralytics)       letterbox, best class, threshold, NMS
``detr``       float ``pixel_values`` -> ``logits``, ``pred_boxes``     sigmoid, threshold, cxcywh in 0..1
               (Hugging Face / transformers.js DETR-family exports)
=============  =====================================================  ===========================================

Whatever the model's input size, boxes come back as ``x1, y1, x2, y2`` pixels of the image given.
Class names come from, first match wins: the ``labels`` argument, a labels file (``labels_path``,
or one ``*labels*.txt`` / ``*.names`` file beside the model), the model's metadata (Ultralytics'
``names``), else COCO (80 classes, or TF's 90 ids for the SSD signatures).

The model is a callable taking ``{"images": [RGB uint8 HxWx3 arrays], "threshold": float}`` and
returning ``{"output": [{"bboxes", "labels", "scores"} per image]}``: the result format of a
RoboML ``VisionModel``, so a component reads local and remote answers alike.
"""

from __future__ import annotations

import ast
import json
import logging
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import ConfigError, InferenceError
from ..support.install_hint import install_hint
from .device import DEVICES, resolve_device
from .model_files import resolve_model_file

__all__ = ["COCO80_LABELS", "DEFAULT_VISION_ENV_VAR", "DEFAULT_VISION_FILE", "DEFAULT_VISION_REPO",
           "LocalVisionModel", "coco90_labels",
           "nms", "read_labels_file", "resize_rgb"]

_logger = logging.getLogger("agents_core.engines.local_vision")

#: The default detector: a D-FINE (the DEIM family) COCO model exported to ONNX, from the hub.
DEFAULT_VISION_REPO = "onnx-community/dfine_n_coco-ONNX"
DEFAULT_VISION_FILE = "onnx/model.onnx"
#: A local ONNX detector to use instead of the hub default when no model path is given (an offline
#: robot, or a recipe written for another default, such as upstream's ``enable_local_classifier``).
DEFAULT_VISION_ENV_VAR = "AGENTS_VISION_MODEL"

#: The 80 COCO class names in the order detectors trained on COCO number them (0-based).
COCO80_LABELS: tuple[str, ...] = (
    "person", "bicycle", "car", "motorcycle", "airplane", "bus", "train", "truck", "boat", "traffic light",
    "fire hydrant", "stop sign", "parking meter", "bench", "bird", "cat", "dog", "horse", "sheep", "cow",
    "elephant", "bear", "zebra", "giraffe", "backpack", "umbrella", "handbag", "tie", "suitcase", "frisbee",
    "skis", "snowboard", "sports ball", "kite", "baseball bat", "baseball glove", "skateboard", "surfboard",
    "tennis racket", "bottle", "wine glass", "cup", "fork", "knife", "spoon", "bowl", "banana", "apple",
    "sandwich", "orange", "broccoli", "carrot", "hot dog", "pizza", "donut", "cake", "chair", "couch",
    "potted plant", "bed", "dining table", "toilet", "tv", "laptop", "mouse", "remote", "keyboard", "cell phone",
    "microwave", "oven", "toaster", "sink", "refrigerator", "book", "clock", "vase", "scissors", "teddy bear",
    "hair drier", "toothbrush",
)
# The ids COCO's 90-id numbering (TF Object Detection API) leaves unused.
_COCO90_GAPS = frozenset({12, 26, 29, 30, 45, 66, 68, 69, 71, 83})

#: Largest image side accepted; beyond it the frame is refused rather than resized (memory, latency).
MAX_INPUT_SIDE = 4096


def coco90_labels() -> dict[int, str]:
    """COCO's class names by their 90-id numbering (1 = person, ..., with gaps), as TF detectors use."""
    ids = (i for i in range(1, 91) if i not in _COCO90_GAPS)
    return dict(zip(ids, COCO80_LABELS, strict=True))


def read_labels_file(path: str | Path, first_id: int = 0) -> dict[int, str]:
    """Class names from a file: lines ``"<id> <name>"``, or one name per line (numbered from ``first_id``),
    or JSON (a list, or an object of id -> name)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot read the labels file {p}: {exc}") from exc
    if p.suffix.lower() == ".json":
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ConfigError(f"labels file {p} is not valid JSON: {exc}") from exc
        return _labels_from_data(data, first_id, str(p))
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    split = [line.split(maxsplit=1) for line in lines]
    if lines and all(len(s) == 2 and s[0].isdigit() for s in split):
        return {int(s[0]): s[1] for s in split}
    return {first_id + i: name for i, name in enumerate(lines)}


def _labels_from_data(data: Any, first_id: int, source: str) -> dict[int, str]:
    if isinstance(data, list | tuple):
        return {first_id + i: str(name) for i, name in enumerate(data)}
    if isinstance(data, Mapping):
        try:
            return {int(k): str(v) for k, v in data.items()}
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"labels from {source} must map integer ids to names: {exc}") from exc
    raise ConfigError(f"labels from {source} must be a list of names or a mapping id -> name, "
                      f"got {type(data).__name__}")


def resize_rgb(image: npt.NDArray[np.uint8], width: int, height: int) -> npt.NDArray[np.uint8]:
    """``image`` resized to ``width`` x ``height``: bilinear with Pillow when installed, else nearest."""
    if image.shape[1] == width and image.shape[0] == height:
        return image
    try:
        from PIL import Image as PILImage  # noqa: PLC0415  (optional: better quality and faster)
    except ImportError:
        rows = (np.arange(height) * image.shape[0] / height).astype(np.intp)
        cols = (np.arange(width) * image.shape[1] / width).astype(np.intp)
        nearest: npt.NDArray[np.uint8] = image[rows][:, cols]
        return nearest
    resized: npt.NDArray[np.uint8] = np.asarray(
        PILImage.fromarray(np.ascontiguousarray(image)).resize((width, height), PILImage.Resampling.BILINEAR))
    return resized


def nms(boxes: npt.NDArray[np.float32], scores: npt.NDArray[np.float32], classes: npt.NDArray[np.int64],
        iou_threshold: float) -> npt.NDArray[np.intp]:
    """Indices kept by greedy non-maximum suppression, per class, best score first."""
    if boxes.shape[0] == 0:
        return np.zeros(0, np.intp)
    # Offsetting each class far apart makes one pass suppress within classes only.
    offset = classes.astype(np.float32)[:, None] * (float(boxes.max()) + 1.0)
    b = boxes + offset
    areas = np.clip(b[:, 2] - b[:, 0], 0, None) * np.clip(b[:, 3] - b[:, 1], 0, None)
    order = np.argsort(-scores, kind="stable")
    keep: list[int] = []
    while order.size:
        i = int(order[0])
        keep.append(i)
        rest = order[1:]
        w = np.clip(np.minimum(b[i, 2], b[rest, 2]) - np.maximum(b[i, 0], b[rest, 0]), 0, None)
        h = np.clip(np.minimum(b[i, 3], b[rest, 3]) - np.maximum(b[i, 1], b[rest, 1]), 0, None)
        inter = w * h
        iou = inter / np.maximum(areas[i] + areas[rest] - inter, 1e-9)
        order = rest[iou <= iou_threshold]
    return np.asarray(keep, np.intp)


def _ssd_outputs(outputs: Sequence[npt.NDArray[Any]]) -> tuple[npt.NDArray[Any], npt.NDArray[Any]]:
    """(boxes, class scores) of a raw SSD: boxes are ``[1,N,1,4]``, or the ``[1,N,4]`` one when both are rank 3."""
    first, second = outputs[0], outputs[1]
    if first.ndim == 4 or (second.ndim == 3 and first.shape[-1] == 4 and second.shape[-1] != 4):
        return first, second
    return second, first


def _import_onnxruntime() -> Any:
    try:
        import onnxruntime  # noqa: PLC0415  (optional dependency of the `local` extra)
    except ImportError as exc:
        raise ConfigError("the built-in local vision model needs onnxruntime: "
                          f"{install_hint('local')}") from exc
    return onnxruntime


class LocalVisionModel:
    """An ONNX object detector run in-process by ONNX Runtime.

    :param model_path: an ``.onnx`` file, a directory holding one, or a hub id (see
        :mod:`agents_core.engines.model_files`); None: :data:`DEFAULT_VISION_REPO` from the hub.
    :param device: ``"cpu"``, or ``"cuda"`` (used when onnxruntime's CUDA provider is installed;
        otherwise a warning is logged and the CPU runs the model).
    :param ncpu: CPU threads for the model.
    :param threshold: default minimum score of a detection (an inference may pass its own).
    :param nms_iou: IoU above which the lower-scored of two same-class boxes is dropped.
    :param labels: class names (a list, numbered like the model's classes, or id -> name).
    :param labels_path: a labels file (see :func:`read_labels_file`).
    :param input_height, input_width: the input size of float models whose size is not fixed in the graph.
    """

    def __init__(self, model_path: str | None = None, device: str = "auto", ncpu: int = 1, threshold: float = 0.5,
                 nms_iou: float = 0.5, labels: Sequence[str] | Mapping[int, str] | None = None,
                 labels_path: str | None = None, input_height: int = 640, input_width: int = 640) -> None:
        if device not in DEVICES:
            raise ConfigError(f"LocalVisionModel: device must be one of {list(DEVICES)}, got {device!r}")
        if isinstance(ncpu, bool) or not isinstance(ncpu, int) or ncpu < 1:
            raise ConfigError(f"LocalVisionModel: ncpu must be an int >= 1, got {ncpu!r}")
        ort = _import_onnxruntime()
        self.model_path = self._resolve(model_path)
        self.threshold = float(threshold)
        self.nms_iou = float(nms_iou)
        self.device = device = resolve_device(device, "onnxruntime", ort, "LocalVisionModel")
        self.providers = ["CPUExecutionProvider"]
        if device == "cuda":
            self.providers = ["CUDAExecutionProvider", "CPUExecutionProvider"]
        options = ort.SessionOptions()
        options.intra_op_num_threads = ncpu
        options.inter_op_num_threads = 1
        try:
            self.session = ort.InferenceSession(str(self.model_path), options, providers=self.providers)
        except Exception as exc:
            raise ConfigError(f"LocalVisionModel: {self.model_path} is not a loadable ONNX model: "
                              f"{type(exc).__name__}: {str(exc)[:300]}") from exc
        self.inputs = [(i.name, list(i.shape), i.type) for i in self.session.get_inputs()]
        self.outputs = [(o.name, list(o.shape), o.type) for o in self.session.get_outputs()]
        self.signature = self._detect_signature()
        self.input_height, self.input_width = self._input_size(input_height, input_width)
        self.labels = self._labels(labels, labels_path)
        _logger.info("loaded %s (%s signature) on %s with %d thread(s)", self.model_path.name, self.signature,
                     self.providers[0], ncpu)

    # -- loading ------------------------------------------------------------------------------

    @staticmethod
    def _resolve(model_path: str | None) -> Path:
        if model_path is None:
            local = os.environ.get(DEFAULT_VISION_ENV_VAR)
            if local:
                return resolve_model_file(local, "*.onnx", f"LocalVisionModel model from ${DEFAULT_VISION_ENV_VAR}")
            return resolve_model_file(DEFAULT_VISION_REPO, DEFAULT_VISION_FILE, "LocalVisionModel default model")
        return resolve_model_file(model_path, "*.onnx", "LocalVisionModel model")

    def _found(self) -> str:
        ins = ", ".join(f"{n} {s} {t}" for n, s, t in self.inputs)
        outs = ", ".join(f"{n} {s} {t}" for n, s, t in self.outputs)
        return f"inputs [{ins}]; outputs [{outs}]"

    def _detect_signature(self) -> str:
        ins, outs = self.inputs, self.outputs
        out_names = {n.split(":")[0].lower() for n, _, _ in outs}
        if len(ins) == 1 and ins[0][2] == "tensor(uint8)" and len(ins[0][1]) == 4:
            if {"detection_boxes", "detection_scores", "detection_classes"} <= out_names:
                return "tf_od"
            ranks = sorted(len(s) for _, s, _ in outs)
            if ranks in ([3, 3], [3, 4]):
                return "ssd"
        if len(ins) == 2 and sorted(t for _, _, t in ins) == ["tensor(float)", "tensor(int64)"] and len(outs) == 3:
            return "deim"
        if len(ins) == 1 and ins[0][2] == "tensor(float)" and len(ins[0][1]) == 4:
            if len(outs) == 1 and len(outs[0][1]) == 3:
                return "yolo"
            if len(outs) == 2 and {"logits", "pred_boxes"} <= out_names:
                return "detr"
        raise ConfigError(f"LocalVisionModel: {self.model_path.name} has a signature this detector does not know "
                          f"({self._found()}); known: TF Object Detection / SSD, DEIM / D-FINE, Ultralytics YOLO, "
                          "DETR-family (logits, pred_boxes)")

    def _input_size(self, height: int, width: int) -> tuple[int, int]:
        if self.signature in ("ssd", "tf_od"):
            return height, width  # any size: the graph resizes
        image_input = next(s for _, s, t in self.inputs if t == "tensor(float)")
        h, w = image_input[2], image_input[3]
        return (h if isinstance(h, int) and h > 0 else height), (w if isinstance(w, int) and w > 0 else width)

    def _labels(self, labels: Sequence[str] | Mapping[int, str] | None, labels_path: str | None) -> dict[int, str]:
        first_id = 1 if self.signature == "ssd" else 0  # TF SSD's column c is class id c + 1 (0 was background)
        if labels:
            return _labels_from_data(labels, first_id, "the labels argument")
        if labels_path is None:
            beside = sorted([*self.model_path.parent.glob("*labels*.txt"), *self.model_path.parent.glob("*.names")])
            if len(beside) == 1:
                labels_path = str(beside[0])
        if labels_path is not None:
            return read_labels_file(labels_path, first_id)
        names = self.session.get_modelmeta().custom_metadata_map.get("names")
        if names:
            try:
                return _labels_from_data(ast.literal_eval(names), 0, "the model's metadata")
            except (ValueError, SyntaxError):
                _logger.warning("the model's 'names' metadata is not a list or dict; using COCO names")
        return coco90_labels() if self.signature in ("ssd", "tf_od") else dict(enumerate(COCO80_LABELS))

    # -- inference ----------------------------------------------------------------------------

    def __call__(self, inference_input: Mapping[str, Any]) -> dict[str, Any]:
        """Detect objects in ``inference_input["images"]`` (RGB uint8 HxWx3 arrays).

        Optional keys: ``threshold`` (minimum score), ``get_dataset_labels`` (False: labels are
        the class ids as text). Returns ``{"output": [{"bboxes", "labels", "scores"}, ...]}``.
        """
        images = inference_input.get("images")
        if not isinstance(images, list | tuple) or not images:
            raise InferenceError("LocalVisionModel: the input needs 'images': a non-empty list of RGB arrays")
        threshold = float(inference_input.get("threshold", self.threshold))
        names = bool(inference_input.get("get_dataset_labels", True))
        return {"output": [self.detect(image, threshold, names) for image in images]}

    def detect(self, image: npt.NDArray[Any], threshold: float | None = None,
               dataset_labels: bool = True) -> dict[str, Any]:
        """Boxes (``x1, y1, x2, y2`` pixels of ``image``), labels and scores above ``threshold``."""
        checked = self.check_image(image)
        feeds, meta = self.preprocess(checked)
        outputs = self.session.run(None, feeds)
        return self.postprocess(outputs, meta, self.threshold if threshold is None else threshold, dataset_labels)

    @staticmethod
    def check_image(image: Any) -> npt.NDArray[np.uint8]:
        """``image`` if it is an RGB uint8 HxWx3 array of a size a detector can take, else InferenceError."""
        if not isinstance(image, np.ndarray):
            raise InferenceError(f"LocalVisionModel: expected an RGB numpy array, got {type(image).__name__}")
        if image.dtype != np.uint8:
            raise InferenceError(f"LocalVisionModel: expected uint8 pixels (RGB 0..255), got dtype {image.dtype}")
        if image.ndim != 3 or image.shape[2] != 3:
            raise InferenceError(f"LocalVisionModel: expected an HxWx3 RGB array, got shape {image.shape}")
        height, width = image.shape[:2]
        if height < 1 or width < 1:
            raise InferenceError(f"LocalVisionModel: the image is empty ({height}x{width})")
        if max(height, width) > MAX_INPUT_SIDE:
            raise InferenceError(f"LocalVisionModel: a {height}x{width} image is larger than {MAX_INPUT_SIDE} "
                                 "pixels a side; downscale it first")
        return image

    def preprocess(self, image: npt.NDArray[np.uint8]) -> tuple[dict[str, Any], dict[str, float]]:
        """The model's input feeds for one RGB image, and what post-processing needs to map boxes back."""
        height, width = image.shape[:2]
        meta = {"height": float(height), "width": float(width), "scale": 1.0, "pad_x": 0.0, "pad_y": 0.0}
        if self.signature in ("ssd", "tf_od"):
            return {self.inputs[0][0]: np.ascontiguousarray(image)[None]}, meta
        if self.signature == "yolo":
            # Ultralytics letterboxes: keep the aspect ratio, pad with grey to the input size.
            scale = min(self.input_width / width, self.input_height / height)
            new_w, new_h = max(1, round(width * scale)), max(1, round(height * scale))
            canvas = np.full((self.input_height, self.input_width, 3), 114, np.uint8)
            pad_x, pad_y = (self.input_width - new_w) // 2, (self.input_height - new_h) // 2
            canvas[pad_y:pad_y + new_h, pad_x:pad_x + new_w] = resize_rgb(image, new_w, new_h)
            meta.update(scale=scale, pad_x=float(pad_x), pad_y=float(pad_y))
            resized = canvas
        else:
            resized = resize_rgb(image, self.input_width, self.input_height)
        tensor = (resized.astype(np.float32) * np.float32(1.0 / 255.0)).transpose(2, 0, 1)[None]
        feeds = {}
        for name, _, kind in self.inputs:
            if kind == "tensor(int64)":
                feeds[name] = np.array([[width, height]], np.int64)  # DEIM / D-FINE take (w, h)
            else:
                feeds[name] = np.ascontiguousarray(tensor)
        return feeds, meta

    def postprocess(self, outputs: Sequence[npt.NDArray[Any]], meta: Mapping[str, float], threshold: float,
                    dataset_labels: bool = True) -> dict[str, Any]:
        """The detections of one image from the model's raw outputs (see the module docs)."""
        width, height = meta["width"], meta["height"]
        named = {n.split(":")[0].lower(): o for (n, _, _), o in zip(self.outputs, outputs, strict=True)}
        if self.signature == "ssd":
            boxes_out, scores_out = _ssd_outputs(outputs)
            class_scores = scores_out.reshape(scores_out.shape[1], -1)
            classes = class_scores.argmax(axis=1)
            scores = class_scores[np.arange(classes.size), classes]
            raw = boxes_out.reshape(-1, 4)[:, [1, 0, 3, 2]] * np.array([width, height, width, height], np.float32)
            keep = scores >= threshold
            boxes, scores, classes = raw[keep], scores[keep], classes[keep] + 1
            chosen = nms(boxes, scores, classes, self.nms_iou)
            boxes, scores, classes = boxes[chosen], scores[chosen], classes[chosen]
        elif self.signature == "tf_od":
            scores = named["detection_scores"].reshape(-1)
            classes = named["detection_classes"].reshape(-1).astype(np.int64)
            boxes = named["detection_boxes"].reshape(-1, 4)[:, [1, 0, 3, 2]] * np.array(
                [width, height, width, height], np.float32)
        elif self.signature == "deim":
            by_type = {("labels" if o.dtype == np.int64 else "boxes" if o.ndim == 3 else "scores"): o for o in outputs}
            boxes, scores = by_type["boxes"][0], by_type["scores"][0]
            classes = by_type["labels"][0].astype(np.int64)
        elif self.signature == "detr":
            logits = named["logits"][0]
            probs = 1.0 / (1.0 + np.exp(-logits))
            classes = probs.argmax(axis=1)
            scores = probs[np.arange(classes.size), classes]
            cx, cy, w, h = named["pred_boxes"][0].T
            boxes = np.stack([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2], axis=1) * np.array(
                [width, height, width, height], np.float32)
        else:  # yolo
            boxes, scores, classes = self._yolo(outputs[0], meta, threshold)
        keep = scores >= threshold
        boxes = np.asarray(boxes[keep], np.float32).reshape(-1, 4)
        boxes = np.clip(boxes, 0, np.array([width, height, width, height], np.float32))
        classes = np.asarray(classes[keep], np.int64)
        scores = np.asarray(scores[keep], np.float32)
        order = np.argsort(-scores, kind="stable")
        labels = [self.labels.get(int(c), str(int(c))) if dataset_labels else str(int(c)) for c in classes[order]]
        return {"bboxes": boxes[order], "labels": labels, "scores": scores[order], "class_ids": classes[order]}

    def _yolo(self, out: npt.NDArray[Any], meta: Mapping[str, float],
              threshold: float) -> tuple[npt.NDArray[Any], npt.NDArray[Any], npt.NDArray[Any]]:
        rows = out[0]
        if rows.shape[-1] == 6 and rows.shape[0] > rows.shape[1]:
            # Exported with nms=True: [K, 6] = x1, y1, x2, y2, score, class in letterboxed pixels.
            boxes, scores, classes = rows[:, :4].copy(), rows[:, 4], rows[:, 5].astype(np.int64)
        else:
            if rows.shape[0] < rows.shape[1]:
                rows = rows.T  # [4+C, N] -> [N, 4+C]
            class_scores = rows[:, 4:]
            classes = class_scores.argmax(axis=1)
            scores = class_scores[np.arange(classes.size), classes]
            keep = scores >= threshold
            cx, cy, w, h = rows[keep, :4].T
            boxes = np.stack([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2], axis=1)
            scores, classes = scores[keep], classes[keep]
            chosen = nms(boxes, scores, classes, self.nms_iou)
            boxes, scores, classes = boxes[chosen], scores[chosen], classes[chosen]
        boxes = (boxes - np.array([meta["pad_x"], meta["pad_y"]] * 2, np.float32)) / np.float32(meta["scale"])
        return boxes, scores, classes
