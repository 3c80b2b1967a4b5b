"""A simulated robot arm for the VLA tests: it integrates the commands it gets and publishes its state.

It uses only the transport contract (a publisher and a subscription), so it runs on any transport:
JointState at ``state_rate`` Hz, a camera Image at ``camera_rate`` Hz, and it applies each command
on ``command_topic`` (JointState positions or velocities, a JointTrajectory's first point, a
JointJog's displacements or velocities) to its joints. Every command is recorded.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np

from agents_core.messages import JointJogMsg, JointStateMsg, JointTrajectoryMsg
from agents_core.topics import Topic
from agents_core.transport.contract import Transport


class SimulatedArm:
    """Joints that follow position commands (or integrate velocity commands), publishing their state."""

    def __init__(self, transport: Transport, joints: dict[str, float], *, state_topic: Topic, command_topic: Topic,
                 camera_topic: Topic | None = None, state_rate: float = 100.0, camera_rate: float = 10.0) -> None:
        self.positions = dict(joints)
        self.velocities = dict.fromkeys(joints, 0.0)
        self.commands: list[Any] = []
        self.publish_state = True
        self.hide_joints: set[str] = set()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._state_pub = transport.create_publisher(state_topic)
        self._camera_pub = transport.create_publisher(camera_topic) if camera_topic is not None else None
        self._sub = transport.create_subscription(command_topic, self._on_command)
        self._state_rate = state_rate
        self._camera_rate = camera_rate
        self._thread = threading.Thread(target=self._run, name="sim-arm", daemon=True)
        self._thread.start()

    def _on_command(self, cmd: Any) -> None:
        with self._lock:
            self.commands.append(cmd)
            if isinstance(cmd, JointStateMsg):
                for i, name in enumerate(cmd.name):
                    if len(cmd.position):
                        self.positions[name] = float(cmd.position[i])
                    if len(cmd.velocity):
                        self.velocities[name] = float(cmd.velocity[i])
            elif isinstance(cmd, JointTrajectoryMsg) and cmd.points:
                for i, name in enumerate(cmd.joint_names):
                    self.positions[name] = float(cmd.points[0].positions[i])
            elif isinstance(cmd, JointJogMsg):
                for i, name in enumerate(cmd.joint_names):
                    if len(cmd.displacements):
                        self.positions[name] += float(cmd.displacements[i])
                    if len(cmd.velocities):
                        self.velocities[name] = float(cmd.velocities[i])

    def _run(self) -> None:
        dt = 1.0 / self._state_rate
        next_camera = 0.0
        frame = np.zeros((16, 16, 3), np.uint8)
        while not self._stop.wait(dt):
            with self._lock:
                for name, v in self.velocities.items():
                    self.positions[name] += v * dt
                names = [n for n in self.positions if n not in self.hide_joints]
                state = JointStateMsg(name=names, position=[self.positions[n] for n in names])
            if self.publish_state:
                self._state_pub.publish(state)
            now = time.monotonic()
            if self._camera_pub is not None and now >= next_camera:
                frame[:] = int(now * 10) % 255
                self._camera_pub.publish(frame)
                next_camera = now + 1.0 / self._camera_rate

    def snapshot(self) -> dict[str, float]:
        with self._lock:
            return dict(self.positions)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5.0)
        self._sub.close()
        self._state_pub.close()
        if self._camera_pub is not None:
            self._camera_pub.close()
