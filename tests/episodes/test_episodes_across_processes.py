"""The recorder component in a recipe process of its own, on Zenoh and ROS 2, driven by hooks from this one.

This process publishes the world's topics and drives the component through
``EpisodeRecordingHooks.for_component("episodes", transport=...)`` (its ``execute_method`` service),
then calls its ``record_episode`` action; the files the other process wrote hold what was published.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core.errors import RequestTimeoutError, ServiceUnavailableError
from agents_core.messages import ImageMsg, JointStateMsg
from agents_core.testing.recipes import RecipeTransport, run_recipe

from ..conftest import wait_for

pytest.importorskip("mcap", reason="pip install 'agents-core[record]'")

from agents_core.episodes import EpisodeRecordingHooks, load_episodes
from agents_core.recording import read_recording

from .episodes_recipe import CAMERA, JOINTS

REPO = Path(__file__).resolve().parents[2]


def _when_served(call: Any, timeout: float = 30.0) -> Any:
    deadline = time.monotonic() + timeout
    while True:
        try:
            return call()
        except (ServiceUnavailableError, RequestTimeoutError):
            if time.monotonic() > deadline:
                raise
            time.sleep(0.2)


def test_hooks_drive_a_recorder_in_another_process(recipe_transport: RecipeTransport, tmp_path: Path) -> None:
    if recipe_transport.name == "ros2":
        pytest.importorskip("agents_interfaces", reason="the ROS 2 interfaces are not built")
    directory = tmp_path / "episodes"
    with run_recipe("tests.episodes.episodes_recipe", recipe_transport, tmp_path, ["--directory", str(directory)],
                    cwd=REPO):
        asker = recipe_transport.open_asker()
        joints, camera = asker.create_publisher(JOINTS), asker.create_publisher(CAMERA)
        hooks = EpisodeRecordingHooks.for_component("episodes", transport=asker, task="wave")
        _when_served(lambda: hooks.on_episode_start(0, 42))
        time.sleep(1.0)  # the recipe's subscriptions match ours
        sent = 0
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and sent < 10:
            joints.publish(JointStateMsg(name=["a"], position=[float(sent)]))
            camera.publish(ImageMsg.from_array(np.full((12, 16, 3), sent, np.uint8)))
            sent += 1
            time.sleep(0.05)
        time.sleep(0.5)
        hooks.on_episode_end({"episode": 0, "seed": 42, "success": True, "steps": sent, "rewards": [1.0]})
        reply = asker.request("episodes/execute_method", {"method": "record_episode",
                                                          "kwargs": {"before_s": 5.0, "after_s": 0.3}})
        assert reply["result"]["episode"] == 1
        assert wait_for(lambda: len(list(directory.glob("episode_*.json"))) == 2, timeout=10)
    first, second = load_episodes(directory)
    assert first.success is True and first.task == "wave" and first.extra["seed"] == 42
    assert first.extra["result"] == {"episode": 0, "seed": 42, "success": True, "steps": sent}
    positions = [int(m.value.position[0]) for m in read_recording(first.mcap, topics={"joints"})]
    assert positions == list(range(sent)) and first.topics["camera"]["messages"] == sent
    assert second.trigger == "event" and second.messages == 2 * sent  # the pre-buffer: the last 5 s
