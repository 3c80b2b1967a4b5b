"""Two ROS 2 transports on loopback: kept for the tests that import it; the pair now ships in the plugin."""

from __future__ import annotations

from agents_core.testing.pairs import private_ros_environment, ros2_pair

__all__ = ["private_ros_environment", "ros2_pair"]
