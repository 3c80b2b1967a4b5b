"""The transports an evaluation runs on in these tests, each parameter marked with its transport's name.

Zenoh listens on a loopback port of its own (multicast scouting is off by default); ROS 2 stays on
this host in a private domain.
"""

from __future__ import annotations

import importlib.util
from typing import Any

import pytest

from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.pairs import private_ros_environment

__all__ = ["TRANSPORTS", "transport_options"]

TRANSPORTS = [
    pytest.param("memory", marks=pytest.mark.memory),
    pytest.param("zenoh", marks=[pytest.mark.zenoh, pytest.mark.skipif(
        importlib.util.find_spec("zenoh") is None, reason="zenoh not installed: pip install 'agents-core[zenoh]'")]),
    pytest.param("ros2", marks=[pytest.mark.ros2, pytest.mark.skipif(
        importlib.util.find_spec("rclpy") is None, reason="rclpy not installed: pip install 'agents-core[ros2]'")]),
]


def transport_options(name: str) -> dict[str, Any] | None:
    """The options that keep ``name`` on this host (and set up its environment)."""
    if name == "zenoh":
        return {"listen": [f"tcp/127.0.0.1:{free_tcp_port()}"], "connect": []}
    if name == "ros2":
        private_ros_environment()
    return None
