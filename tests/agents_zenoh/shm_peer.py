"""The receiving process of ``test_shm.py``: a framework Zenoh subscriber of images and point clouds.

``python -m tests.agents_zenoh.shm_peer ENDPOINT NAMESPACE on|off`` connects to ENDPOINT with
``ZenohConfig(shared_memory=...)``, subscribes (inline callbacks) to ``shm/image`` (Image) and
``shm/cloud`` (PointCloud2), and a raw zenoh session (shared memory on or off like the framework's)
subscribes to the same keys to tell whether each sample arrived as a shared-memory block. It prints
one JSON line per event on stdout:

- ``{"src": "raw", "topic": t, "shm": bool}`` per raw sample;
- ``{"src": "fw", "topic": t, "seq": n, "digest": hex, "shape": [...], "dtype": str}`` per value;
- on the String ``shm/check``: ``{"src": "kept", "n": k, "intact": bool}``, whether every value kept
  past its callback (the array itself, no copy made by this process) still holds what it held then.

It prints ``READY`` once subscribed and runs until SIGTERM.
"""

from __future__ import annotations

import hashlib
import json
import signal
import sys
import threading
from typing import Any

import numpy as np
import zenoh

from agents_core import Topic
from agents_core.transport.registry import resolve_transport

TOPICS = {"shm/image": "Image", "shm/cloud": "PointCloud2"}


def _say(record: dict[str, Any]) -> None:
    sys.stdout.write(json.dumps(record) + "\n")
    sys.stdout.flush()


def _array(value: Any) -> np.ndarray[Any, Any]:
    return value.data if hasattr(value, "data") else value.points


def main() -> int:
    endpoint, namespace, flag = sys.argv[1:4]
    shared = flag == "on"
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    bus = resolve_transport("zenoh", mode="peer", listen=[], connect=[endpoint], namespace=namespace,
                            multicast_scouting=False, shared_memory=shared)
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", "[]")
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("transport/shared_memory/enabled", json.dumps(shared))
    raw = zenoh.open(conf)
    kept: list[tuple[np.ndarray[Any, Any], str]] = []
    handles: list[Any] = []

    def on_value(topic: str) -> Any:
        def callback(value: Any) -> None:
            arr = _array(value)
            digest = hashlib.sha256(arr.tobytes()).hexdigest()
            kept.append((arr, digest))  # the array itself, kept past the callback
            _say({"src": "fw", "topic": topic, "seq": int(value.header.frame_id), "digest": digest,
                  "shape": list(arr.shape), "dtype": str(arr.dtype)})
        return callback

    def on_raw(sample: zenoh.Sample) -> None:
        _say({"src": "raw", "topic": str(sample.key_expr), "shm": sample.payload.as_shm() is not None})

    def on_check(_value: Any) -> None:
        intact = all(hashlib.sha256(arr.tobytes()).hexdigest() == digest for arr, digest in kept)
        _say({"src": "kept", "n": len(kept), "intact": intact})

    try:
        for name, type_name in TOPICS.items():
            handles.append(bus.create_subscription(Topic(name, type_name), on_value(name), inline=True))
            handles.append(raw.declare_subscriber(f"{namespace}/{name}", on_raw))
        handles.append(bus.create_subscription(Topic("shm/check", "String"), on_check, inline=True))
        print("READY", flush=True)
        stop.wait(120.0)
    finally:
        for handle in handles:
            (handle.close if hasattr(handle, "close") else handle.undeclare)()
        raw.close()
        bus.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
