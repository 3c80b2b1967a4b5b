"""``examples/evaluate_reacher.py`` runs as a user runs it, on each transport: the expert and the random agent."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from agents_core.testing.helpers import free_tcp_port

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(importlib.util.find_spec("gymnasium") is None or
                                importlib.util.find_spec("mujoco") is None,
                                reason="the sim extra is not installed: pip install 'agents-core[sim]'")


@pytest.mark.parametrize("transport", [
    pytest.param("memory", marks=pytest.mark.memory),
    pytest.param("zenoh", marks=[pytest.mark.zenoh, pytest.mark.skipif(
        importlib.util.find_spec("zenoh") is None, reason="zenoh not installed")]),
    pytest.param("ros2", marks=[pytest.mark.ros2, pytest.mark.skipif(
        importlib.util.find_spec("rclpy") is None, reason="rclpy not installed")]),
])
def test_evaluate_reacher_example(transport: str, tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")]),
           "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_DOMAIN_ID": str(1 + os.getpid() % 100)}
    env.pop("AGENTS_TRANSPORT", None)
    args = ["--transport", transport, "--episodes", "3", "--out", str(tmp_path)]
    if transport == "zenoh":
        args += ["--listen", f"tcp/127.0.0.1:{free_tcp_port()}"]
    proc = subprocess.run([sys.executable, str(ROOT / "examples" / "evaluate_reacher.py"), *args], env=env,
                          capture_output=True, text=True, timeout=240, check=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "expert: 3/3 episodes succeeded (100 %)" in proc.stdout
    assert "random: " in proc.stdout
    meta = json.loads((tmp_path / "expert" / "evaluation.json").read_text(encoding="utf-8"))
    assert meta["transport"] == transport
