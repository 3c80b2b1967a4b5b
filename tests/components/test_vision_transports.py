"""The same Vision recipe file (vision_recipe.py) detects and tracks on memory, zenoh and ros2.

Memory runs in this process; on each cross-process transport (the ``recipe_transport`` fixture)
the recipe runs in a child process (stopped by PID afterwards). On Zenoh this process asks through
the framework's transport; on ROS 2 through a plain rclpy node (sensor_msgs/Image out,
agents_interfaces Detections2D / Trackings in), as any ROS 2 user would. Transports whose extra is
missing are skipped with the reason.
"""

from __future__ import annotations

import threading
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core import Launcher
from agents_core.messages import Header, ImageMsg
from agents_core.testing.pairs import skip_unless_installed
from agents_core.testing.recipes import RecipeTransport, run_recipe
from agents_core.transport.contract import Transport

from ..conftest import wait_for
from . import vision_recipe
from .models_dir import REPO
from .vision_recipe import found_on, needs_ssd, photo

pytestmark = pytest.mark.local_models

PHOTOS = ("astronaut.png", "chelsea.png", "coffee.png")


def _round_trip(publish: Callable[[str, int], None], results: Callable[[], dict[int, Any]], name: str,
                sec: int) -> Any:
    """Publish photo ``name`` stamped ``sec`` until its result arrives (discovery may lose the first ones)."""
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        publish(name, sec)
        if wait_for(lambda: sec in results(), timeout=3):
            return results()[sec]
    pytest.fail(f"no result for {name} within 30 s")


def _check_framework_side(transport: Transport) -> None:
    detections: dict[int, Any] = {}
    trackings: dict[int, Any] = {}
    subs = [transport.create_subscription(vision_recipe.DETECTIONS,
                                          lambda d: detections.setdefault(d.header.stamp_ns // 10**9, d)),
            transport.create_subscription(vision_recipe.TRACKINGS,
                                          lambda t: trackings.setdefault(t.header.stamp_ns // 10**9, t))]
    pub = transport.create_publisher(vision_recipe.CAMERA)

    def publish(name: str, sec: int) -> None:
        pixels = np.full((480, 640, 3), 90, np.uint8) if name == "blank" else photo(name)
        pub.publish(ImageMsg(data=pixels, encoding="rgb8", header=Header(stamp_ns=sec * 10**9 + 5, frame_id="cam")))

    try:
        for sec, name in enumerate(PHOTOS, start=100):
            det = _round_trip(publish, lambda: detections, name, sec)
            assert found_on(name, det.labels, det.scores, det.boxes), (name, det.labels, det.scores)
            assert det.header.frame_id == "cam"
            assert wait_for(lambda s=sec: s in trackings, timeout=10)
            track = trackings[sec]
            assert track.ids.dtype == np.int64 and len(track.ids) >= 1
            assert vision_recipe.KNOWN[name][0] in track.labels
        blank = _round_trip(publish, lambda: detections, "blank", 200)
        assert blank.labels == []
    finally:
        pub.close()
        for sub in subs:
            sub.close()


def test_recipe_on_memory() -> None:
    needs_ssd()
    launcher = Launcher("memory")
    launcher.add_pkg(components=[vision_recipe.build()])
    with launcher:
        _check_framework_side(launcher.transport)


def _ask_through_the_framework(recipe_transport: RecipeTransport) -> None:
    _check_framework_side(recipe_transport.open_asker())


#: How a user of each transport asks the recipe; the framework's own transport where none is named.
USER_SIDE: dict[str, Callable[[RecipeTransport], None]] = {"ros2": lambda _: _plain_rclpy_side()}


def test_recipe_in_its_own_process(recipe_transport: RecipeTransport, tmp_path: Path) -> None:
    needs_ssd()
    if recipe_transport.name == "ros2":
        skip_unless_installed("ros2", "agents_interfaces")
    with run_recipe("tests.components.vision_recipe", recipe_transport, tmp_path, cwd=REPO):
        USER_SIDE.get(recipe_transport.name, _ask_through_the_framework)(recipe_transport)


def _plain_rclpy_side() -> None:
    with warnings.catch_warnings():
        # rosidl's parser imports lark, which imports the deprecated sre_parse (as agents_ros2.conversions notes).
        warnings.simplefilter("ignore", DeprecationWarning)
        import rclpy  # noqa: PLC0415
        import rosidl_generator_py  # noqa: F401, PLC0415  (loaded lazily by the first publisher otherwise)
        from agents_interfaces.msg import Detections2D, Trackings  # noqa: PLC0415
        from rclpy.executors import SingleThreadedExecutor  # noqa: PLC0415
        from sensor_msgs.msg import Image  # noqa: PLC0415

    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("plain_vision_user", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    detections: dict[int, Any] = {}
    trackings: dict[int, Any] = {}
    node.create_subscription(Detections2D, "/detections", lambda m: detections.setdefault(m.header.stamp.sec, m), 10)
    node.create_subscription(Trackings, "/trackings", lambda m: trackings.setdefault(m.header.stamp.sec, m), 10)
    camera = node.create_publisher(Image, "/camera", 10)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()

    def publish(name: str, sec: int) -> None:
        pixels = photo(name)
        msg = Image(height=pixels.shape[0], width=pixels.shape[1], encoding="rgb8", is_bigendian=0,
                    step=pixels.shape[1] * 3)
        msg.header.stamp.sec = sec
        msg.header.frame_id = "plain_camera"
        msg.data = pixels.tobytes()
        camera.publish(msg)

    try:
        for sec, name in enumerate(PHOTOS, start=300):
            det = _round_trip(publish, lambda: detections, name, sec)
            boxes = [[b.top_left_x, b.top_left_y, b.bottom_right_x, b.bottom_right_y] for b in det.boxes]
            assert found_on(name, list(det.labels), list(det.scores), boxes), (name, list(det.labels))
            assert det.header.frame_id == "plain_camera"
            assert wait_for(lambda s=sec: s in trackings, timeout=10)
            track = trackings[sec]
            assert len(track.ids) >= 1 and vision_recipe.KNOWN[name][0] in list(track.labels)
            assert all(isinstance(i, int) for i in track.ids)
    finally:
        executor.shutdown()
        spinner.join(timeout=5)
        node.destroy_node()
        rclpy.shutdown(context=context)
