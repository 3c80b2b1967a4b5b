"""A recipe-like process serving a 640x480 camera through the Foxglove bridge.

``python -m tests.foxglove.camera_bridge --transport memory|zenoh|ros2 [--max-clients N]
[--handshake-timeout S] [--allow-origin O]``: publishes rgb8 frames at 30 Hz on ``camera`` (on
Zenoh from a second session over loopback TCP), serves them with a ``FoxgloveBridge`` on an
ephemeral port, prints ``READY <port>`` and runs until killed.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from typing import Any

import numpy as np

from agents_core.foxglove import FoxgloveBridge, FoxgloveSettings
from agents_core.messages import ImageMsg
from agents_core.testing.helpers import free_tcp_port
from agents_core.topics import Topic

CAMERA = Topic("camera", "Image")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--transport", default="memory")
    parser.add_argument("--max-clients", type=int)
    parser.add_argument("--handshake-timeout", type=float)
    parser.add_argument("--allow-origin", action="append")
    args = parser.parse_args()
    with contextlib.ExitStack() as stack:
        transport: Any
        if args.transport == "memory":
            from agents_core.transport.memory import MemoryTransport  # noqa: PLC0415

            transport = stack.enter_context(MemoryTransport())
            camera_side = transport
        elif args.transport == "ros2":  # two DDS participants in a private domain, discovery on this host
            from agents_core.testing.pairs import ros2_pair  # noqa: PLC0415

            transport, camera_side = stack.enter_context(ros2_pair())
        else:
            from agents_core.transport.registry import resolve_transport  # noqa: PLC0415

            endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
            transport = stack.enter_context(resolve_transport(
                "zenoh", mode="peer", listen=[endpoint], connect=[], multicast_scouting=False))
            camera_side = stack.enter_context(resolve_transport(
                "zenoh", mode="peer", listen=[], connect=[endpoint], multicast_scouting=False))
        given = {"max_clients": args.max_clients, "handshake_timeout": args.handshake_timeout,
                 "allowed_origins": args.allow_origin}
        settings = FoxgloveSettings(port=0, **{k: v for k, v in given.items() if v is not None})
        bridge = stack.enter_context(FoxgloveBridge(transport, [CAMERA], settings))
        publisher = camera_side.create_publisher(CAMERA)
        frame = np.random.default_rng(1).integers(0, 255, (480, 640, 3), dtype=np.uint8)
        print(f"READY {bridge.port}", flush=True)
        while True:
            publisher.publish(ImageMsg(data=frame, encoding="rgb8"))
            time.sleep(1 / 30)


if __name__ == "__main__":
    sys.exit(main())
