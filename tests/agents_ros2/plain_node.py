"""A plain rclpy node that talks to the recipe of tests/agents_ros2/recipe.py, as any ROS 2 user would.

It imports rclpy, the standard message packages and agents_interfaces, and nothing of
agents_core. Run as ``python tests/agents_ros2/plain_node.py``; it prints one JSON object with what it
observed on stdout and exits 0 (or 1 with ``{"error": ...}``). Every wait is bounded.
"""

from __future__ import annotations

import json
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
from agents_interfaces.msg import Detections2D
from agents_interfaces.srv import JsonCall
from lifecycle_msgs.srv import ChangeState, GetState
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import Image
from std_msgs.msg import String

STEP_TIMEOUT = 20.0


def wait_until(predicate: Callable[[], bool], timeout: float = STEP_TIMEOUT, interval: float = 0.05,
               action: Callable[[], None] | None = None) -> bool:
    """Poll ``predicate`` (running ``action`` before each poll) until true or ``timeout`` passes."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if action is not None:
            action()
        if predicate():
            return True
        time.sleep(interval)
    return predicate()


def make_image(width: int, height: int, bright: tuple[int, int], sec: int, encoding: str = "rgb8",
               data_len: int | None = None) -> Image:
    """An rgb8 image, black but for one white pixel at ``bright`` (column, row)."""
    msg = Image(height=height, width=width, encoding=encoding, is_bigendian=0, step=width * 3)
    msg.header.stamp.sec = sec
    msg.header.stamp.nanosec = 123
    msg.header.frame_id = "plain_camera"
    pixels = bytearray(width * height * 3)
    col, row = bright
    start = (row * width + col) * 3
    pixels[start:start + 3] = b"\xff\xff\xff"
    msg.data = bytes(pixels[: data_len if data_len is not None else len(pixels)])
    return msg


class PlainNode:
    """Publishers, subscriptions and clients of the interop scenario, spun on a background thread."""

    def __init__(self) -> None:
        self.node = Node("plain_interop_node")
        self.chat_in = self.node.create_publisher(String, "/chat_in", 10)
        self.camera = self.node.create_publisher(Image, "/camera", 10)
        self.replies: list[str] = []
        self.detections: list[Detections2D] = []
        self.node.create_subscription(String, "/chat_out", lambda m: self.replies.append(m.data), 10)
        self.node.create_subscription(Detections2D, "/objects", self.detections.append, 10)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def call(self, srv_type: Any, name: str, request: Any, timeout: float = STEP_TIMEOUT) -> Any:
        client = self.node.create_client(srv_type, name)
        try:
            if not wait_until(client.service_is_ready, timeout):
                raise RuntimeError(f"service {name} never appeared")
            future = client.call_async(request)
            if not wait_until(future.done, timeout):
                raise RuntimeError(f"service {name} did not answer")
            return future.result()
        finally:
            self.node.destroy_client(client)

    def state(self, component: str) -> str:
        return str(self.call(GetState, f"/{component}/get_state", GetState.Request()).current_state.label)

    def change(self, component: str, transition: str) -> bool:
        request = ChangeState.Request()
        request.transition.label = transition
        return bool(self.call(ChangeState, f"/{component}/change_state", request).success)

    def execute(self, component: str, method: str) -> Any:
        reply = self.call(JsonCall, f"/{component}/execute_method",
                          JsonCall.Request(request_json=json.dumps({"method": method})))
        if not reply.success:
            raise RuntimeError(f"{component}.{method} failed: {reply.error}")
        return json.loads(reply.response_json)["result"]

    def chat_round_trip(self, text: str, timeout: float = STEP_TIMEOUT) -> bool:
        """Publish ``text`` until its reversal comes back (discovery may lose the first ones)."""
        return wait_until(lambda: text[::-1] in self.replies, timeout, interval=0.2,
                          action=lambda: self.chat_in.publish(String(data=text)))

    def image_round_trip(self, image: Image) -> Detections2D | None:
        """Publish ``image`` until a detection stamped like it arrives; return that detection."""
        def found() -> Detections2D | None:
            return next((d for d in self.detections if d.header.stamp.sec == image.header.stamp.sec), None)

        wait_until(lambda: found() is not None, interval=0.2, action=lambda: self.camera.publish(image))
        return found()

    def close(self) -> None:
        self.executor.shutdown()
        self.thread.join(timeout=5.0)
        self.node.destroy_node()


def scenario(plain: PlainNode) -> dict[str, Any]:
    out: dict[str, Any] = {}
    out["initial_states"] = {}
    for component in ("relay", "detector"):
        wait_until(lambda c=component: plain.state(c) == "active")
        out["initial_states"][component] = plain.state(component)

    out["chat_reply"] = plain.chat_round_trip("hello from plain rclpy")

    good = plain.image_round_trip(make_image(8, 6, bright=(5, 2), sec=1001))
    out["detection"] = None if good is None else {
        "labels": list(good.labels), "scores": list(good.scores),
        "box": [good.boxes[0].top_left_x, good.boxes[0].top_left_y, good.boxes[0].bottom_right_x,
                good.boxes[0].bottom_right_y],
        "stamp": [good.header.stamp.sec, good.header.stamp.nanosec], "frame_id": good.header.frame_id,
        "image_size": [good.image.width, good.image.height], "image_encoding": good.image.encoding,
    }

    # Two messages the recipe cannot convert, then a good one: it must be served.
    plain.camera.publish(make_image(8, 6, bright=(1, 1), sec=2001, encoding="yuv422"))
    plain.camera.publish(make_image(8, 6, bright=(1, 1), sec=2002, data_len=100))
    after = plain.image_round_trip(make_image(4, 4, bright=(3, 0), sec=2003))
    out["served_after_malformed"] = after is not None and list(after.labels) == ["brightest_4x4"]
    out["malformed_answered"] = sorted({d.header.stamp.sec for d in plain.detections} & {2001, 2002})
    out["detector_counters"] = plain.execute("detector", "input_counters")

    # Drive the relay's lifecycle from outside.
    out["deactivate"] = plain.change("relay", "deactivate")
    out["state_after_deactivate"] = plain.state("relay")
    plain.replies.clear()
    out["reply_while_inactive"] = plain.chat_round_trip("anyone there", timeout=1.5)
    out["activate"] = plain.change("relay", "activate")
    out["state_after_activate"] = plain.state("relay")
    out["reply_after_activate"] = plain.chat_round_trip("back again")
    out["activate_twice"] = plain.change("relay", "activate")
    out["agents_core_imported"] = any(name.split(".")[0] == "agents_core" for name in sys.modules)
    return out


def main() -> int:
    rclpy.init()
    plain = PlainNode()
    try:
        result = scenario(plain)
    except Exception as exc:
        print(json.dumps({"error": f"{type(exc).__name__}: {exc}"}), flush=True)
        return 1
    finally:
        plain.close()
        rclpy.try_shutdown()
    print(json.dumps(result), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
