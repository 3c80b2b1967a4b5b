"""Object detection and tracking on photos, with the shared COCO detector.

A Vision component runs the COCO SSD MobileNetV2 detector (ONNX, the ``local`` extra) on
``camera`` (Image) and publishes ``detections`` and ``trackings`` (people, cats and cups). The
example feeds it the photos in ``../shared/images`` (``--images DIR``) and prints what it found::

    python examples/vision_tracking.py --once
    python examples/vision_tracking.py --model my_detector.onnx --images my_photos/

On a robot, a camera driver publishes ``camera`` instead (ROS 2: a ``sensor_msgs/Image`` topic).
"""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
from example_cli import SHARED, make_launcher, parser, run

from agents_core import Launcher, Topic
from agents_core.components import Vision
from agents_core.config import VisionConfig
from agents_core.messages import Header, ImageMsg

CAMERA = Topic("camera", "Image")
DETECTIONS = Topic("detections", "Detections")
TRACKINGS = Topic("trackings", "Trackings")


def main(argv: list[str] | None = None) -> None:
    """Run the detector and feed it the photos."""
    p = parser(__doc__)
    p.add_argument("--model", type=Path, default=SHARED / "models" / "coco-ssd-mobilenet-v2" /
                   "coco_ssd_mobilenet_v2.onnx", help="an ONNX detector")
    p.add_argument("--images", type=Path, default=SHARED / "images", help="a folder of photos")
    args = p.parse_args(argv)
    photos = sorted(args.images.glob("*.png")) if args.images.is_dir() else []
    if not args.model.is_file() or not photos:
        sys.exit(f"no detector at {args.model} or no photos in {args.images} (see --help)")
    from PIL import Image as PILImage  # noqa: PLC0415  (the local extra: after the check above, for its message)

    config = VisionConfig(enable_local_model=True, local_model_path=str(args.model), threshold=0.5,
                          labels_to_track=["person", "cat", "cup"])
    vision = Vision(inputs=[CAMERA], outputs=[DETECTIONS, TRACKINGS], config=config, component_name="eyes")
    launcher = make_launcher(args)
    launcher.add_pkg(components=[vision])
    seen: dict[int, Any] = {}
    all_seen = threading.Event()

    def feed(running: Launcher) -> None:
        def tracked(value: Any) -> None:
            index = value.header.stamp_ns // 10**9
            if index not in seen and 0 <= index < len(photos):
                seen[index] = value
                ids = [int(i) for i in value.ids]
                print(f"{photos[index].name}: tracking {list(value.labels)} ids {ids}", flush=True)
                if len(seen) == len(photos):
                    all_seen.set()

        running.transport.create_subscription(TRACKINGS, tracked)
        camera = running.transport.create_publisher(CAMERA)
        for index, path in enumerate(photos):
            with PILImage.open(path) as img:
                pixels = np.asarray(img.convert("RGB"), dtype=np.uint8)
            # Publish until the result comes: on Zenoh / ROS 2 the first frames may precede discovery.
            while index not in seen and not all_seen.is_set():
                camera.publish(ImageMsg(data=pixels, encoding="rgb8",
                                        header=Header(stamp_ns=index * 10**9, frame_id="camera")))
                time.sleep(0.5)

    run(launcher, args, on_ready=feed, done=all_seen)


if __name__ == "__main__":
    main()
