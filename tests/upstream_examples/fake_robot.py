"""A scripted fake robot for upstream's Memory recipes: odometry that moves, a camera, a goal-point follower.

:class:`FakeRobot` runs on any transport (the launcher's memory transport, or an asker on Zenoh or
ROS 2). A background thread publishes, at ``rate`` Hz, the robot's pose on ``odom`` (Odometry, map
frame) and, at ``camera_rate`` Hz while the camera is on, the photo of the place it stands in on
``image_raw``. A test drives it place by place with :meth:`FakeRobot.visit` (which waits for a
condition, such as enough detections of the place's object, bounded by a timeout); a
PoseStamped on ``goal_point`` makes it drive there in a straight line at ``speed`` m/s, as a
navigation stack would, and :meth:`FakeRobot.arrived_at` says when it is there.

The photos are the real ones in ``../shared/images`` (``AGENTS_SHARED`` overrides ``../shared``):
:func:`photo` skips the test, naming the folder, when they are absent.
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
from attrs import define

from agents_core.messages import Header, OdometryMsg, PoseMsg
from agents_core.ros import Topic
from agents_core.testing.helpers import wait_for

__all__ = ["SHARED_IMAGES", "FakeRobot", "Place", "photo"]

ROOT = Path(__file__).resolve().parents[2]
#: The shared photos (a cat, a cup of coffee on a table, ...).
SHARED_IMAGES = Path(os.environ.get("AGENTS_SHARED", str(ROOT.parent / "shared"))) / "images"


def photo(name: str) -> npt.NDArray[np.uint8]:
    """The shared photo ``name`` as RGB pixels; skips the test when the photos (or Pillow) are absent."""
    path = SHARED_IMAGES / name
    if not path.is_file():
        pytest.skip(f"the shared photo {name} is not in {SHARED_IMAGES} (set AGENTS_SHARED to the shared folder)")
    pil = pytest.importorskip("PIL.Image", reason="Pillow reads the shared photos (pip install 'agents-core[local]')")
    with pil.open(path) as img:
        return np.asarray(img.convert("RGB"))


@define(frozen=True)
class Place:
    """Somewhere the robot can stand: its name, where it is (map frame, m) and the photo its camera sees there."""

    name: str
    x: float
    y: float
    image: npt.NDArray[np.uint8] | None = None


class FakeRobot:
    """A robot that publishes where it is and what it sees, and drives to the goal points it is sent.

    :param transport: where to publish and subscribe (any :class:`~agents_core.transport.contract.Transport`).
    :param rate: odometry messages per second (also the driving loop's rate).
    :param camera_rate: camera frames per second while the camera is on.
    :param speed: driving speed towards a goal point (m/s).
    """

    def __init__(self, transport: Any, *, rate: float = 10.0, camera_rate: float = 8.0, speed: float = 5.0,
                 odom: str = "odom", camera: str = "image_raw", goal: str = "goal_point") -> None:
        self.rate, self.camera_rate, self.speed = rate, camera_rate, speed
        self._lock = threading.Lock()
        self._x = self._y = 0.0
        self._image: npt.NDArray[np.uint8] | None = None
        self._target: tuple[float, float] | None = None
        #: Every goal point received, as (x, y, z).
        self.goals: list[tuple[float, float, float]] = []
        self._stop = threading.Event()
        self._odom = transport.create_publisher(Topic(name=odom, msg_type="Odometry"))
        self._camera = transport.create_publisher(Topic(name=camera, msg_type="Image"))
        self._goal_sub = transport.create_subscription(Topic(name=goal, msg_type="PoseStamped"), self._on_goal)
        self._thread = threading.Thread(target=self._run, name="fake-robot", daemon=True)

    # -- driving it ----------------------------------------------------------------------------

    def __enter__(self) -> FakeRobot:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop the thread and close the publishers and the subscription."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(5.0)
        for endpoint in (self._odom, self._camera, self._goal_sub):
            endpoint.close()

    @property
    def position(self) -> tuple[float, float]:
        """Where the robot is now (x, y)."""
        with self._lock:
            return self._x, self._y

    def visit(self, place: Place, until: Callable[[], bool], timeout: float = 60.0) -> bool:
        """Stand at ``place`` with its photo on the camera until ``until()`` (at most ``timeout`` s).

        The camera is off while the robot moves, and for a moment on each side, so that a frame of
        one place is never stored at another's position. Returns whether ``until()`` became true.
        """
        self.camera_off()
        with self._lock:
            self._x, self._y, self._target = place.x, place.y, None
        time.sleep(3.0 / self.rate)  # the new position reaches the subscribers before the first frame
        with self._lock:
            self._image = place.image
        try:
            return wait_for(until, timeout=timeout, interval=0.1)
        finally:
            self.camera_off()

    def camera_off(self, settle: float = 1.0) -> None:
        """Stop the camera, then wait ``settle`` s for the frames in flight to be processed."""
        with self._lock:
            self._image = None
        time.sleep(settle)

    def arrived_at(self, x: float, y: float, tolerance: float = 0.05) -> bool:
        """Whether the robot stands within ``tolerance`` m of (x, y)."""
        rx, ry = self.position
        return math.hypot(rx - x, ry - y) <= tolerance

    # -- the robot's side ----------------------------------------------------------------------

    def _on_goal(self, pose: Any) -> None:
        position = getattr(pose, "position", None)
        if position is None or len(position) < 2:
            return
        x, y = float(position[0]), float(position[1])
        if not (math.isfinite(x) and math.isfinite(y)):
            return
        with self._lock:
            self.goals.append((x, y, float(position[2]) if len(position) > 2 else 0.0))
            self._target = (x, y)

    def _run(self) -> None:
        period = 1.0 / self.rate
        next_frame = time.monotonic()
        # Bounded by close(): the loop ends when _stop is set.
        while not self._stop.wait(period):
            with self._lock:
                self._drive(period)
                x, y, image = self._x, self._y, self._image
            self._odom.publish(OdometryMsg(pose=PoseMsg(position=[x, y, 0.0]), header=Header(frame_id="map"),
                                           child_frame_id="base_link"))
            now = time.monotonic()
            if image is not None and now >= next_frame:
                self._camera.publish(image)
                next_frame = now + 1.0 / self.camera_rate

    def _drive(self, period: float) -> None:
        """One step towards the goal point, if there is one (the lock is held)."""
        if self._target is None:
            return
        dx, dy = self._target[0] - self._x, self._target[1] - self._y
        distance, step = math.hypot(dx, dy), self.speed * period
        if distance <= step:
            self._x, self._y, self._target = self._target[0], self._target[1], None
        else:
            self._x, self._y = self._x + dx * step / distance, self._y + dy * step / distance
