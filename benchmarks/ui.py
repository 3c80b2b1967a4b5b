"""Web UI: latency from a topic value to a WebSocket client of the UI, against a raw subscription.

In one process on the memory transport: a value is published on a topic, and the time until it
arrives is measured, one value at a time, two ways, on separate publishes interleaved in one run (each
round times one of each, alternating which goes first):

- ``framework``: through the UI (``agents_core.ui``, a real uvicorn server on 127.0.0.1, its default
  settings: no WebSocket compression): the hub's subscription encodes the frame (JSON; a JPEG for an
  image, by simplejpeg when installed), the event loop fans it out, and a WebSocket client (the
  ``websockets`` library) receives and parses it;
- ``raw``: a plain transport subscription's callback receives the value, on a second topic that the UI
  does not show (on the same topic the UI's own encode could run first on the delivery path and
  inflate the raw side).

Payloads: ``string`` (a short String) and ``image`` (a 640x480 rgb8 Image, sent to the client as
JPEG; ``image_bgr8``: the same in a camera's bgr8). The ratio shows what serving a browser costs over
reading the topic in-process.

Binary clients get the UI's default preview size (``UISettings.image_preview``: 640x480 goes as 320x240);
JSON clients the whole image.

``image_encode_floor``: the UI's JPEG encode of the same image alone (``frames.image_bytes`` at the
preview size, timed in the same rounds as a third measurement) against the same raw hops: the least the
``image`` figure can be, whatever the rest of the path costs.

``python -m benchmarks.ui --count N`` prints the records.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

from .common import available, emit, image_pixels, percentile

#: payload -> (value, the client's frames, the server's image_format)
PAYLOADS = {"string": ("string", "json", "jpeg"), "image": ("image", "binary", "jpeg"),
            "image_json": ("image", "json", "jpeg"), "image_raw": ("image", "binary", "raw"),
            "image_bgr8": ("image_bgr8", "binary", "jpeg")}


def _value(payload: str, seq: int) -> Any:
    if payload == "string":
        return f"hello robot {seq}"
    pixels = image_pixels().copy()
    pixels[0, 0, 0] = seq % 256
    if payload == "image_bgr8":  # a camera's (OpenCV's, many ROS drivers') channel order
        from agents_core.messages import ImageMsg  # noqa: PLC0415

        return ImageMsg(data=pixels[:, :, ::-1].copy(), encoding="bgr8")
    return pixels


def _latencies(payload: str, count: int, warmup: int, frames: str = "json",
               image_format: str = "jpeg") -> dict[str, list[float]]:
    """Interleaved: each round publishes once on the UI's topic (timed to the WebSocket client) and once
    on a second topic that only a raw subscription reads (timed to its callback), alternating which
    goes first. Separate topics keep the UI's encode off the raw side's delivery path."""
    from websockets.sync.client import connect  # noqa: PLC0415

    from agents_core import Topic  # noqa: PLC0415
    from agents_core.messages import ImageMsg  # noqa: PLC0415
    from agents_core.transport import MemoryTransport  # noqa: PLC0415
    from agents_core.ui import LocalRecipe, UISettings  # noqa: PLC0415
    from agents_core.ui.frames import image_bytes  # noqa: PLC0415
    from agents_core.ui.server import UIServer  # noqa: PLC0415

    type_name = "String" if payload == "string" else "Image"
    shown, raw_topic = Topic("bench", type_name), Topic("bench_raw", type_name)
    transport = MemoryTransport()
    got = threading.Event()
    raw_sub = transport.create_subscription(raw_topic, lambda _: got.set())
    server = UIServer(LocalRecipe([]), transport, inputs=[], outputs=[shown],
                      settings=UISettings(port=0, image_format=image_format)).start()
    publisher, raw_publisher = transport.create_publisher(shown), transport.create_publisher(raw_topic)
    out: dict[str, list[float]] = {"framework": [], "raw": []}
    floor = payload == "image" and image_format == "jpeg"
    if floor:
        out["encode"] = []
    query = "topics=bench" + ("&frames=binary" if frames == "binary" else "")
    try:
        with connect(f"ws://127.0.0.1:{server.port}/api/outputs?{query}", max_size=None, open_timeout=10) as ws:

            def through_ui(value: Any) -> float:
                start = time.perf_counter()
                publisher.publish(value)
                message = ws.recv(timeout=10)
                if isinstance(message, str):
                    json.loads(message)
                return time.perf_counter() - start

            def raw(value: Any) -> float:
                got.clear()
                start = time.perf_counter()
                raw_publisher.publish(value)
                if not got.wait(10):
                    raise RuntimeError("the raw subscription got nothing in 10 s")
                return time.perf_counter() - start

            # At the size the UI sends a binary client (the live view) by default.
            def encode(value: Any, preview: int | None = UISettings().image_preview) -> float:
                image = ImageMsg.from_array(value)
                start = time.perf_counter()
                image_bytes(image, image_format, preview)
                return time.perf_counter() - start

            for seq in range(warmup + count):
                first, second = (through_ui, raw) if seq % 2 else (raw, through_ui)
                times = {f: f(_value(payload, seq)) for f in (first, second, *([encode] if floor else []))}
                if seq >= warmup:
                    out["raw"].append(times[raw] * 1000)
                    out["framework"].append(times[through_ui] * 1000)
                    if floor:
                        out["encode"].append(times[encode] * 1000)
    finally:
        server.stop()
        raw_sub.close()
        transport.close()
    return out


def measure(count: int, warmup: int, progress: Callable[[str], None]) -> list[dict[str, Any]]:
    """The records of every payload, framework and raw."""
    records = []
    for payload, (value, frames, image_format) in PAYLOADS.items():
        samples = _latencies(value, count if payload == "string" else max(5, count // 4), warmup, frames,
                             image_format)
        encode = samples.pop("encode", None)
        figures = [(payload, mode, values) for mode, values in samples.items()]
        if encode is not None:  # the floor: the encode alone against the same raw hops
            figures += [("image_encode_floor", "framework", encode), ("image_encode_floor", "raw", samples["raw"])]
        for name, mode, values in figures:
            records.append({"suite": "ui", "transport": "memory", "mode": mode, "payload": name,
                            "n": len(values), "latency_ms": {"p50": percentile(values, 50),
                                                             "p99": percentile(values, 99)}})
        fw, raw = (next(r for r in records if r["mode"] == m and r["payload"] == payload)
                   for m in ("framework", "raw"))
        progress(f"{'ui':<10} {payload:<10} value -> WebSocket client p50 {fw['latency_ms']['p50']:.3f} ms vs raw "
                 f"subscription {raw['latency_ms']['p50']:.3f} ms (n={fw['n']})")
    return records


def run_suite(settings: dict[str, Any], progress: Callable[[str], None]) -> tuple[list[dict[str, Any]],
                                                                                   list[dict[str, str]]]:
    """The UI figures; (records, skipped)."""
    missing = [m for m in ("starlette", "uvicorn", "PIL") if not available(m)]
    if missing:
        reason = f"the ui extra is not installed (missing {missing}): pip install 'agents-core[ui]'"
        return [], [{"suite": "ui", "transport": "memory", "mode": "both", "reason": reason}]
    return measure(int(settings["ui_count"]), int(settings["ui_warmup"]), progress), []


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--count", type=int, default=200)
    args = parser.parse_args(argv)
    for record in measure(args.count, 20, lambda line: print(line, file=sys.stderr, flush=True)):
        emit(record)
    return 0


if __name__ == "__main__":
    sys.exit(main())
