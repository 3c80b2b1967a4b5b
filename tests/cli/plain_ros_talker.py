"""A plain rclpy node (no agents_core): publishes ``/plain_chatter`` (std_msgs/String) and ``/plain_empty``.

Run as ``python tests/cli/plain_ros_talker.py SECONDS``; it publishes both at 10 Hz for that long.
"""

from __future__ import annotations

import sys
import time

import rclpy
from std_msgs.msg import Empty, String


def main(seconds: float) -> None:
    rclpy.init()
    node = rclpy.create_node("plain_ros_talker")
    chatter = node.create_publisher(String, "/plain_chatter", 10)
    empty = node.create_publisher(Empty, "/plain_empty", 10)
    print("PLAIN NODE UP", flush=True)
    end = time.monotonic() + seconds
    n = 0
    while time.monotonic() < end:
        n += 1
        chatter.publish(String(data=f"plain {n}"))
        empty.publish(Empty())
        time.sleep(0.1)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 60.0)
