"""On ROS 2 the CLI sees plain ROS nodes' topics too: a plain rclpy publisher in another process."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from agents_core.testing.pairs import missing_requirement
from tests.cli.helpers import REPO, cli, cli_env, wait_until

pytestmark = [pytest.mark.ros2, pytest.mark.slow,
              pytest.mark.skipif(missing_requirement("ros2") is not None, reason=str(missing_requirement("ros2")))]


def test_plain_ros_topics_are_listed_and_echoed(tmp_path: Path) -> None:
    log = tmp_path / "plain.log"
    with log.open("wb") as out:
        plain = subprocess.Popen([sys.executable, "tests/cli/plain_ros_talker.py", "90"], cwd=REPO, env=cli_env(),
                                 stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        topics: dict[str, dict[str, object]] = {}

        def listed() -> bool:
            nonlocal topics
            done = cli("topics", "list", "--transport", "ros2", "--json")
            assert done.returncode == 0, done.stderr
            topics = {t["name"]: t for t in json.loads(done.stdout)}
            return "plain_chatter" in topics and "plain_empty" in topics
        assert wait_until(listed, timeout=60.0), (topics, log.read_text())
        assert topics["plain_chatter"]["msg_type"] == "String"  # std_msgs/String has an agents_core type
        assert topics["plain_empty"]["msg_type"] == "std_msgs/msg/Empty"  # shown under its ROS type

        done = cli("topics", "echo", "/plain_chatter", "--transport", "ros2", "--count", "1", "--json")
        assert done.returncode == 0, done.stderr
        assert json.loads(done.stdout)["value"].startswith("plain ")

        done = cli("topics", "echo", "plain_empty", "--transport", "ros2", "--count", "1")
        assert done.returncode == 1
        assert done.stderr.strip() == ("error: topic 'plain_empty' carries std_msgs/msg/Empty, which has no "
                                       "agents_core message type")
    finally:
        plain.kill()
        plain.wait(timeout=10)
