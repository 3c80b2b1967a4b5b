"""The ROS 2 transport (work in progress: see the project's issue on the ROS 2 adapter)."""

from __future__ import annotations

import rclpy  # noqa: F401  # the dependency check: a missing extra fails here, with the extra named by the registry

__all__: list[str] = []
