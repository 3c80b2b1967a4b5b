"""One Vision recipe, run unchanged on every transport by test_vision_transports.py.

``python -m tests.components.vision_recipe --transport zenoh --listen tcp/127.0.0.1:PORT`` (or
``--transport ros2``, or ``memory`` in-process through :func:`build`) brings up a Vision
component on the real COCO SSD MobileNetV2 (``../shared/models``, see models_dir.py): ``camera``
(Image) in, ``detections`` (Detections) and ``trackings`` (Trackings of people, cats and cups)
out. It prints ``READY`` on stdout once active and runs until SIGTERM / SIGINT.
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest

from agents_core import Launcher, Topic
from agents_core.components import Vision
from agents_core.config import VisionConfig
from agents_core.testing.pairs import skip_unless_installed

from .models_dir import SHARED_MODELS
from .recipe_main import serve, transport_options

#: The real COCO detector (SSD MobileNetV2, TF Object Detection signature) and the test photos.
SSD_MODEL = SHARED_MODELS / "coco-ssd-mobilenet-v2" / "coco_ssd_mobilenet_v2.onnx"
SHARED_IMAGES = SHARED_MODELS.parent / "images"

#: Where each photo's object is (x1, y1, x2, y2 pixels, drawn by hand): a detection must overlap it (IoU >= 0.5).
KNOWN = {"astronaut.png": ("person", (0, 0, 420, 512)), "chelsea.png": ("cat", (0, 0, 420, 300)),
         "coffee.png": ("cup", (170, 15, 410, 300))}


def needs_ssd() -> str:
    """The SSD model file, or a skip naming what is missing."""
    skip_unless_installed("", "onnxruntime", reason="onnxruntime is not installed (pip install 'agents-core[local]')")
    skip_unless_installed("", "PIL", reason="Pillow is not installed (pip install 'agents-core[local]'): it reads the "
                                            "test photos")
    if not SSD_MODEL.is_file() or not (SHARED_IMAGES / "astronaut.png").is_file():
        pytest.skip(f"the COCO SSD model or the test images are not in {SHARED_MODELS} (set AGENTS_SHARED_MODELS)")
    return str(SSD_MODEL)


def photo(name: str) -> npt.NDArray[np.uint8]:
    """A test photo as RGB uint8 pixels."""
    from PIL import Image as PILImage  # noqa: PLC0415

    with PILImage.open(SHARED_IMAGES / name) as img:
        return np.asarray(img.convert("RGB"))


def iou(a: Any, b: Any) -> float:
    """IoU of two x1 y1 x2 y2 boxes."""
    w = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    h = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = w * h
    return float(inter / ((a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter))


def found_on(name: str, labels: list[str], scores: Any, boxes: Any) -> bool:
    """Whether detections include the photo's object with score >= 0.5 overlapping its known region."""
    label, region = KNOWN[name]
    return any(lb == label and float(s) >= 0.5 and iou(box, region) >= 0.5
               for lb, s, box in zip(labels, scores, boxes, strict=True))

CAMERA = Topic("camera", "Image")
DETECTIONS = Topic("detections", "Detections")
TRACKINGS = Topic("trackings", "Trackings")


def build() -> Vision:
    """The recipe's one component (the part that is the same on every transport)."""
    config = VisionConfig(enable_local_model=True, local_model_path=str(SSD_MODEL), threshold=0.5,
                          labels_to_track=["person", "cat", "cup"], warmup=True)
    return Vision(inputs=[CAMERA], outputs=[DETECTIONS, TRACKINGS], config=config, component_name="eyes")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--transport", required=True, choices=["memory", "zenoh", "ros2", "rmw_zenoh"])
    parser.add_argument("--listen", default=None, help="zenoh: the endpoint to listen on")
    args = parser.parse_args(argv)
    launcher = Launcher(transport=args.transport, transport_options=transport_options(args.transport, args.listen))
    launcher.add_pkg(components=[build()])
    serve(launcher)


if __name__ == "__main__":
    main()
