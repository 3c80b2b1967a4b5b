"""The vision path: frames per second through the Vision component against a direct onnxruntime loop.

Same model (the real COCO SSD MobileNetV2 of ``../shared/models``), same 640x480 frame (a photo
with a motorcycle, so post-processing has boxes to keep), one CPU thread on both sides, the same
pre- and post-processing code (:class:`agents_core.engines.local_vision.LocalVisionModel`'s
``preprocess`` / ``session.run`` / ``postprocess``):

- raw: a loop in one process calling those three on the frame; fps = frames / time, and the
  per-frame time's p50 / p99 as its "latency".
- framework: a Vision component (``enable_local_model``) in a *serve* process on Zenoh, and a
  *drive* process (the camera) publishing Image frames and subscribing to Detections over Zenoh
  (peer sessions on 127.0.0.1). Latency: camera-to-Detections, one frame in flight, from just
  before publishing to the Detections reaching the camera process. Throughput: two frames in
  flight (the next frame is sent when a result arrives), so the detector never waits for the
  network; fps = results / time.

``python -m benchmarks.vision --role raw|serve|drive ...`` is one side; :func:`run_suite` runs them.
"""

from __future__ import annotations

import argparse
import logging
import os
import statistics
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .common import REPO, ChildFailed, Children, StopFlag, available, child_env, emit, free_tcp_port, log, percentile

SHARED_MODELS = Path(os.environ.get("AGENTS_SHARED_MODELS", REPO.parent / "shared" / "models"))
MODEL = SHARED_MODELS / "coco-ssd-mobilenet-v2" / "coco_ssd_mobilenet_v2.onnx"
PHOTO = SHARED_MODELS.parent / "images" / "motorcycle_left.png"
PAYLOAD = "ssd_640x480"
RESULT_TIMEOUT = 30.0


def unavailable_reason() -> str | None:
    """Why the vision suite cannot run here, or None."""
    for module, extra in (("onnxruntime", "local"), ("PIL", "local"), ("zenoh", "zenoh")):
        if not available(module):
            return f"{module} is not installed (pip install 'agents-core[{extra}]')"
    if not MODEL.is_file() or not PHOTO.is_file():
        return f"the COCO SSD model or the photos are not in {SHARED_MODELS} (set AGENTS_SHARED_MODELS)"
    return None


def frame() -> Any:
    """The benchmark frame: the motorcycle photo at 640x480, RGB uint8."""
    import numpy as np  # noqa: PLC0415
    from PIL import Image as PILImage  # noqa: PLC0415

    from agents_core.engines.local_vision import resize_rgb  # noqa: PLC0415

    with PILImage.open(PHOTO) as img:
        return resize_rgb(np.asarray(img.convert("RGB")), 640, 480)


def _ms(samples_ns: list[int]) -> dict[str, float]:
    ms = [s / 1e6 for s in samples_ns]
    return {"n": len(ms), "p50": statistics.median(ms), "p99": percentile(ms, 99.0), "mean": statistics.fmean(ms)}


# -- raw ------------------------------------------------------------------------------------------


def run_raw(frames: int, seconds: float) -> None:
    from agents_core.engines.local_vision import LocalVisionModel  # noqa: PLC0415

    model = LocalVisionModel(str(MODEL), ncpu=1, threshold=0.5)
    image = frame()

    def once() -> dict[str, Any]:
        checked = model.check_image(image)
        feeds, meta = model.preprocess(checked)
        return model.postprocess(model.session.run(None, feeds), meta, 0.5)

    for _ in range(3):
        once()  # warm-up
    times: list[int] = []
    for _ in range(frames):
        start = time.perf_counter_ns()
        found = once()
        times.append(time.perf_counter_ns() - start)
    count, start_s = 0, time.perf_counter()
    while time.perf_counter() - start_s < seconds:
        once()
        count += 1
    elapsed = time.perf_counter() - start_s
    emit({"suite": "vision", "transport": "zenoh", "payload": PAYLOAD, "mode": "raw", "fps": count / elapsed,
          "frames": count, "latency_ms": _ms(times), "labels": found["labels"]})


# -- framework ------------------------------------------------------------------------------------


def _topics() -> tuple[Any, Any]:
    from agents_core import QoSConfig, Topic  # noqa: PLC0415

    return Topic("bench/camera", "Image", qos_profile=QoSConfig(depth=10)), Topic("bench/objects", "Detections")


def run_serve(endpoint: str) -> None:
    from agents_core import Launcher  # noqa: PLC0415
    from agents_core.components.vision import Vision  # noqa: PLC0415
    from agents_core.config import VisionConfig  # noqa: PLC0415

    camera, objects = _topics()
    config = VisionConfig(enable_local_model=True, local_model_path=str(MODEL), ncpu_local_model=1, threshold=0.5,
                          warmup=True, log_level="warning")
    vision = Vision(inputs=[camera], outputs=[objects], config=config, component_name="bench_vision")
    launcher = Launcher(transport="zenoh", transport_options={"mode": "peer", "listen": [endpoint], "connect": [],
                                                              "multicast_scouting": False})
    launcher.add_pkg(components=[vision])
    stop = StopFlag()
    with launcher:
        print("READY", flush=True)
        while not stop.wait(0.2):
            pass


def _throughput(send: Callable[[], int], wait: Callable[[int], bool], seconds: float) -> tuple[int, float]:
    """Results received in ``seconds`` with two frames in flight, and the time taken."""
    in_flight = [send(), send()]
    start_s = time.perf_counter()
    done = 0
    while time.perf_counter() - start_s < seconds:
        if not wait(in_flight[0]):
            raise RuntimeError(f"no result for frame {in_flight[0]}")
        in_flight.pop(0)
        done += 1
        in_flight.append(send())
    elapsed = time.perf_counter() - start_s
    for key in in_flight:
        wait(key)
    return done, elapsed


def run_drive(endpoint: str, frames: int, seconds: float) -> None:
    from agents_core.messages import Header, ImageMsg  # noqa: PLC0415
    from agents_core.transport import resolve_transport  # noqa: PLC0415

    camera, objects = _topics()
    pixels = frame()
    transport = resolve_transport("zenoh", mode="peer", listen=[], connect=[endpoint], multicast_scouting=False)
    arrived: dict[int, int] = {}
    cond = threading.Condition()
    labels: list[str] = []

    def on_result(msg: Any) -> None:
        now = time.perf_counter_ns()
        with cond:
            arrived[msg.header.stamp_ns] = now
            labels[:] = msg.labels
            cond.notify_all()

    sub = transport.create_subscription(objects, on_result)
    pub = transport.create_publisher(camera)
    seq = 0

    def send() -> tuple[int, int]:
        nonlocal seq
        seq += 1
        started = time.perf_counter_ns()
        pub.publish(ImageMsg(data=pixels, encoding="rgb8", header=Header(stamp_ns=seq)))
        return seq, started

    def wait(key: int, timeout: float = RESULT_TIMEOUT) -> bool:
        with cond:
            return cond.wait_for(lambda: key in arrived, timeout=timeout)

    try:
        # Discovery: send until one result comes back, then warm up.
        deadline = time.monotonic() + RESULT_TIMEOUT
        while not wait(send()[0], timeout=1.0):
            if time.monotonic() > deadline:
                raise RuntimeError("the Vision component never answered")
        for _ in range(3):
            if not wait(send()[0]):
                raise RuntimeError("no result in warm-up")
        latencies: list[int] = []
        for _ in range(frames):
            key, started = send()
            if not wait(key):
                raise RuntimeError(f"no result for frame {key}")
            latencies.append(arrived[key] - started)
        first = seq + 1
        done, elapsed = _throughput(lambda: send()[0], wait, seconds)
        lost = sum(1 for k in range(first, seq + 1) if k not in arrived)
        emit({"suite": "vision", "transport": "zenoh", "payload": PAYLOAD, "mode": "framework", "fps": done / elapsed,
              "frames": done, "lost": lost, "latency_ms": _ms(latencies), "labels": list(labels)})
    finally:
        pub.close()
        sub.close()
        transport.close()


# -- the runner -----------------------------------------------------------------------------------


def run_suite(settings: dict[str, Any], children: Children,
              progress: Callable[[str], None]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """The raw loop, then the Vision component on Zenoh (serve + drive processes); (records, skipped)."""
    reason = unavailable_reason()
    if reason is not None:
        progress(f"vision: skipped: {reason}")
        return [], [{"suite": "vision", "transport": "zenoh", "mode": "both", "reason": reason}]
    frames, seconds = str(settings["vision_frames"]), str(settings["vision_seconds"])
    records: list[dict[str, Any]] = []
    skipped: list[dict[str, str]] = []
    env = child_env()
    try:
        for _ in range(settings.get("rounds", 1)):
            raw = children.start("vision_raw", ["-m", "benchmarks.vision", "--role", "raw", "--frames", frames,
                                                "--seconds", seconds], env)
            records += list(raw.records(timeout=RESULT_TIMEOUT + float(seconds) * 3))
            children.stop(raw)
            endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
            serve = children.start("vision_serve", ["-m", "benchmarks.vision", "--role", "serve", "--endpoint",
                                                    endpoint], env)
            serve.wait_ready(60.0)
            drive = children.start("vision_drive", ["-m", "benchmarks.vision", "--role", "drive", "--endpoint",
                                                    endpoint, "--frames", frames, "--seconds", seconds], env)
            records += list(drive.records(timeout=RESULT_TIMEOUT + float(seconds) * 3))
            children.stop(drive)
            children.stop(serve)
        for r in records:
            progress(f"{'vision':<10} {'zenoh':<6} {r['mode']:<9} {PAYLOAD:<12} {r['fps']:6.1f} frames/s   latency "
                     f"p50 {r['latency_ms']['p50']:6.1f} ms  p99 {r['latency_ms']['p99']:6.1f} ms")
    except ChildFailed as exc:
        progress(f"vision: FAILED: {str(exc).splitlines()[0]}")
        skipped.append({"suite": "vision", "transport": "zenoh", "mode": "both", "reason": str(exc)[-1500:]})
    return records, skipped


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--role", required=True, choices=["raw", "serve", "drive"])
    parser.add_argument("--endpoint", default=None)
    parser.add_argument("--frames", type=int, default=50, help="latency samples")
    parser.add_argument("--seconds", type=float, default=5.0, help="throughput measuring time")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr)
    if args.role == "raw":
        run_raw(args.frames, args.seconds)
    elif args.role == "serve":
        run_serve(args.endpoint)
    else:
        run_drive(args.endpoint, args.frames, args.seconds)
    log(f"vision {args.role} done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
