"""A child process that floods a Zenoh topic with camera frames (for the episode recorder's memory bound).

``python -m tests.episodes.flood_publisher --listen tcp/127.0.0.1:PORT --frames N --side S``: waits
(bounded) until a subscriber matches, publishes N fresh S x S RGB frames as fast as it can, prints
``sent N`` and exits.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from agents_core import Topic
from agents_core.messages import ImageMsg
from agents_core.transport.registry import resolve_transport


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--listen", required=True)
    parser.add_argument("--frames", type=int, default=1000)
    parser.add_argument("--side", type=int, default=256)
    parser.add_argument("--start-after", type=float, default=3.0)
    args = parser.parse_args()
    transport = resolve_transport("zenoh", mode="peer", listen=[args.listen], connect=[], multicast_scouting=False)
    try:
        pub = transport.create_publisher(Topic("flood", "Image"))
        print("ready", flush=True)
        time.sleep(args.start_after)  # the recorder connects meanwhile
        rng = np.random.default_rng(0)
        for i in range(args.frames):
            pixels = rng.integers(0, 255, (args.side, args.side, 3), dtype=np.uint8)
            pub.publish(ImageMsg.from_array(pixels))
            if i % 50 == 49:
                time.sleep(0.005)  # let the receiving side keep up a little: it is the bound under test, not Zenoh
        print(f"sent {args.frames}", flush=True)
        time.sleep(1.0)
    finally:
        transport.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
