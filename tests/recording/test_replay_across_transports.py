"""A recording made on Zenoh plays into the same recipe on ROS 2, and one made on ROS 2 plays back into Zenoh.

The Vision recipe (the real COCO detector, the shared photos) runs in a child process each time.
First it is recorded on Zenoh (as in test_record_vision_zenoh.py); then the recipe runs on ROS 2
(``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, a private domain) and the Zenoh recording's camera
frames are played into it through :func:`~agents_core.testing.replay.replay_into` while a
:class:`~agents_core.recording.Recorder` on ROS 2 records the run; its detections must equal the
recorded ones field for field. Finally that ROS 2 recording is played into the recipe on Zenoh.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

import pytest

from agents_core.testing.recipes import RecipeTransport, open_recipe_transport, run_recipe

from ..components import vision_recipe
from ..components.models_dir import REPO
from ..components.vision_recipe import needs_ssd
from .test_record_vision_zenoh import PHOTOS, _record_the_recipe

pytestmark = [pytest.mark.local_models, pytest.mark.zenoh, pytest.mark.ros2, pytest.mark.slow]

pytest.importorskip("mcap.reader", reason="pip install 'agents-core[record]'")
pytest.importorskip("zenoh", reason="pip install 'agents-core[zenoh]'")
pytest.importorskip("rclpy", reason="pip install 'agents-core[ros2]' in a sourced ROS 2 environment")

COMPARE: dict[str, Any] = {"detections": "exact",
                           "trackings": lambda old, new: sorted(old.labels) == sorted(new.labels)}


def _ros2() -> RecipeTransport:
    """ROS 2 on this host: the domain the environment names (a test runner's own), else the harness's private one."""
    if os.environ.get("ROS_DOMAIN_ID", "").strip().isdigit():
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        return RecipeTransport("ros2", domain_id=int(os.environ["ROS_DOMAIN_ID"]))
    return open_recipe_transport("ros2")


def test_zenoh_recording_into_ros2_and_back(tmp_path: Path) -> None:
    needs_ssd()
    from agents_core.recording import Recorder, read_recording  # noqa: PLC0415
    from agents_core.testing.replay import replay_into  # noqa: PLC0415

    zenoh_file, _ = _record_the_recipe(tmp_path)

    # -- Zenoh -> ROS 2: the recipe on ROS 2 answers the recorded frames as it did on Zenoh --------------
    ros_file = tmp_path / "on_ros2.mcap"
    ros = _ros2()
    (tmp_path / "ros2").mkdir()
    with run_recipe("tests.components.vision_recipe", ros, tmp_path / "ros2", cwd=REPO):
        asker = ros.open_asker()
        recorder = Recorder(asker, ros_file, topics=[vision_recipe.CAMERA, vision_recipe.DETECTIONS,
                                                     vision_recipe.TRACKINGS], include_status=False,
                            flush_interval_s=0.2)
        recorder.start()
        try:
            report = replay_into(asker, zenoh_file, inputs=["camera"], outputs=["detections", "trackings"],
                                 compare=COMPARE, timeout_per_input=30.0)
            time.sleep(1.0)  # the recorder's own deliveries of the last answers
        finally:
            stats = recorder.stop()
    report.assert_ok()
    assert report.compared >= 2 * len(PHOTOS)
    assert stats.errors == 0 and stats.dropped == 0, stats

    # The ROS 2 recording holds the frames and the answers, the same detections as the Zenoh one.
    recorded = {(m.topic, m.value.header.stamp_ns) for m in read_recording(ros_file) if m.topic == "detections"}
    on_zenoh = {(m.topic, m.value.header.stamp_ns) for m in read_recording(zenoh_file) if m.topic == "detections"}
    assert recorded == on_zenoh and len(recorded) == len(PHOTOS)

    # -- ROS 2 -> Zenoh: the recording made on ROS 2 plays into the recipe on Zenoh -----------------------
    zenoh = open_recipe_transport("zenoh")
    (tmp_path / "zenoh").mkdir()
    with run_recipe("tests.components.vision_recipe", zenoh, tmp_path / "zenoh", cwd=REPO):
        back = replay_into(zenoh.open_asker(), ros_file, inputs=["camera"], outputs=["detections", "trackings"],
                           compare=COMPARE, timeout_per_input=30.0)
    back.assert_ok()
    assert back.compared >= 2 * len(PHOTOS)
