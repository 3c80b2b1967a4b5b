"""The same Vision recipe file (vision_recipe.py) detects and tracks on memory, zenoh and ros2.

Memory runs in this process; zenoh and ros2 run the recipe in a child process (stopped by PID
afterwards). On Zenoh this process asks through the framework's transport; on ROS 2 through a
plain rclpy node (sensor_msgs/Image out, agents_interfaces Detections2D / Trackings in), as any
ROS 2 user would. Transports whose extra is missing are skipped with the reason.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core import Launcher
from agents_core.messages import Header, ImageMsg
from agents_core.transport.contract import Transport

from ..conftest import free_tcp_port, wait_for
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


@contextmanager
def _recipe(args: list[str], tmp_path: Path) -> Iterator[subprocess.Popen[str]]:
    log = (tmp_path / "recipe.log").open("w")
    proc = subprocess.Popen([sys.executable, "-m", "tests.components.vision_recipe", *args], cwd=REPO,
                            env=dict(os.environ, PYTHONUNBUFFERED="1"), stdout=subprocess.PIPE, stderr=log, text=True)
    try:
        ready: list[str] = []
        reader = threading.Thread(target=lambda: ready.append(proc.stdout.readline()), daemon=True)  # type: ignore[union-attr]
        reader.start()
        reader.join(60)
        if not ready or ready[0].strip() != "READY":
            log.flush()
            pytest.fail(f"recipe did not start: {(tmp_path / 'recipe.log').read_text()[-2000:]}")
        yield proc
    finally:
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=10)
        if proc.stdout is not None:
            proc.stdout.close()
        log.close()


@pytest.mark.zenoh
def test_recipe_on_zenoh(tmp_path: Path) -> None:
    needs_ssd()
    if importlib.util.find_spec("zenoh") is None:
        pytest.skip("zenoh transport not available here: the zenoh extra is not installed")
    from agents_zenoh.transport import ZenohTransport  # noqa: PLC0415

    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    with _recipe(["--transport", "zenoh", "--listen", endpoint], tmp_path):
        asker = ZenohTransport(mode="peer", listen=[], connect=[endpoint], multicast_scouting=False)
        try:
            _check_framework_side(asker)
        finally:
            asker.close()


@pytest.mark.ros2
def test_recipe_on_ros2_seen_by_a_plain_rclpy_node(tmp_path: Path) -> None:
    needs_ssd()
    if importlib.util.find_spec("rclpy") is None or importlib.util.find_spec("agents_interfaces") is None:
        pytest.skip("ros2 transport not available here: rclpy or agents_interfaces is not installed")
    from agents_core.testing.pairs import private_ros_environment  # noqa: PLC0415

    private_ros_environment()
    with _recipe(["--transport", "ros2"], tmp_path):
        _plain_rclpy_side()


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
