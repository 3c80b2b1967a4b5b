"""Interop: a recipe on Launcher(transport="ros2") and a plain rclpy node, in two other processes.

The recipe (tests/agents_ros2/recipe.py) runs as real ROS 2 lifecycle nodes; the plain node
(tests/agents_ros2/plain_node.py, which imports no agents_core) publishes std_msgs/String and
sensor_msgs/Image into it, receives its String and agents_interfaces/Detections2D outputs, sends
images it cannot convert, reads its counters over a JsonCall service, and drives a component's
lifecycle through lifecycle_msgs services. Discovery stays on this host, in a private domain.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("rclpy", reason="needs the ros2 extra")
pytest.importorskip("agents_interfaces", reason="needs agents_interfaces (pip install --no-build-isolation "
                                                "./interfaces)")

pytestmark = [pytest.mark.ros2, pytest.mark.slow]

REPO = Path(__file__).resolve().parents[2]
PLAIN_NODE = Path(__file__).with_name("plain_node.py")


def _private_env() -> dict[str, str]:
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    # A domain of this test run's own (distinct from the conformance pair's), 1..100.
    env["ROS_DOMAIN_ID"] = str(1 + (os.getpid() + 50) % 100)
    env["PYTHONUNBUFFERED"] = "1"
    return env


def _stop(proc: subprocess.Popen[Any], grace: float) -> None:
    """Ask ``proc`` to stop (SIGTERM), then kill it by PID if it has not exited in ``grace`` s."""
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=grace)
        except subprocess.TimeoutExpired:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)


@pytest.fixture
def recipe(tmp_path: Path) -> Iterator[tuple[subprocess.Popen[Any], Path]]:
    log = tmp_path / "recipe.log"
    with log.open("w") as sink:
        proc = subprocess.Popen([sys.executable, "-m", "tests.agents_ros2.recipe"], cwd=REPO, env=_private_env(),
                                stdout=sink, stderr=subprocess.STDOUT)
    try:
        yield proc, log
    finally:
        _stop(proc, grace=15)


def test_plain_rclpy_node_talks_to_a_recipe(recipe: tuple[subprocess.Popen[Any], Path]) -> None:
    proc, log = recipe
    try:
        done = subprocess.run([sys.executable, str(PLAIN_NODE)], check=False, cwd=REPO, env=_private_env(),
                              capture_output=True, text=True, timeout=240)
    except subprocess.TimeoutExpired as exc:
        pytest.fail(f"plain node timed out; recipe log:\n{log.read_text()[-3000:]}\nplain node: {exc.stderr!r}")
    assert proc.poll() is None, f"the recipe died:\n{log.read_text()[-3000:]}"
    lines = [line for line in done.stdout.splitlines() if line.startswith("{")]
    assert lines, f"no result from the plain node (rc={done.returncode}):\n{done.stderr[-3000:]}"
    result = json.loads(lines[-1])
    assert "error" not in result, f"{result['error']}\nrecipe log:\n{log.read_text()[-3000:]}"
    assert done.returncode == 0, f"the plain node exited with {done.returncode}:\n{done.stderr[-3000:]}"

    assert result["agents_core_imported"] is False
    assert result["initial_states"] == {"relay": "active", "detector": "active"}
    assert result["chat_reply"] is True

    detection = result["detection"]
    assert detection is not None, "no Detections2D came back for a good image"
    assert detection["labels"] == ["brightest_8x6"]
    assert detection["box"] == [5.0, 2.0, 6.0, 3.0]
    assert detection["scores"] == [1.0]
    assert detection["stamp"] == [1001, 123], "the image's header stamp must survive the recipe"
    assert detection["frame_id"] == "plain_camera"
    assert detection["image_size"] == [8, 6]
    assert detection["image_encoding"] == "rgb8"

    # Malformed images: skipped (no detection for them), counted, logged with the reason, and
    # the next good image is still served.
    assert result["malformed_answered"] == []
    assert result["served_after_malformed"] is True
    assert result["detector_counters"]["decode_errors"] >= 2
    assert result["detector_counters"]["callback_errors"] == 0

    assert result["deactivate"] is True
    assert result["state_after_deactivate"] == "inactive"
    assert result["reply_while_inactive"] is False
    assert result["activate"] is True
    assert result["state_after_activate"] == "active"
    assert result["reply_after_activate"] is True
    assert result["activate_twice"] is False, "activate from active is not a valid transition"

    _stop(proc, grace=15)
    text = log.read_text()
    assert "does not decode as Image" in text and "yuv422" in text, text[-3000:]
    assert proc.returncode == 0, f"the recipe did not stop cleanly (rc={proc.returncode}):\n{text[-3000:]}"
    assert "recipe: stopped cleanly" in text
