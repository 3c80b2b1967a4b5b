"""ROS 2 conversions of joint states and commands: ``sensor_msgs/JointState``, ``trajectory_msgs``
JointTrajectory(Point) and ``agents_interfaces/JointJog``."""

from __future__ import annotations

from typing import Any

import numpy as np
from sensor_msgs.msg import JointState as RosJointState
from trajectory_msgs.msg import JointTrajectory as RosJointTrajectory
from trajectory_msgs.msg import JointTrajectoryPoint as RosJointTrajectoryPoint

from agents_core import messages as m

from .base import RosConversion, ai, as_numpy, duration_from_ros, duration_to_ros, header_from_ros, header_to_ros, seq

__all__ = ["CONVERSIONS"]


def _joint_state_to_ros(v: m.JointStateMsg) -> RosJointState:
    out = RosJointState(name=list(v.name))
    header_to_ros(v.header, out.header)
    out.position = seq("d", v.position, np.float64)
    out.velocity = seq("d", v.velocity, np.float64)
    out.effort = seq("d", v.effort, np.float64)
    return out


def _joint_state_from_ros(msg: RosJointState) -> m.JointStateMsg:
    return m.JointStateMsg(name=list(msg.name), position=as_numpy(msg.position, np.float64),
                           velocity=as_numpy(msg.velocity, np.float64), effort=as_numpy(msg.effort, np.float64),
                           header=header_from_ros(msg.header))


def _trajectory_point_to_ros(v: m.JointTrajectoryPointMsg) -> RosJointTrajectoryPoint:
    out = RosJointTrajectoryPoint(time_from_start=duration_to_ros(v.time_from_start))
    out.positions = seq("d", v.positions, np.float64)
    out.velocities = seq("d", v.velocities, np.float64)
    out.accelerations = seq("d", v.accelerations, np.float64)
    out.effort = seq("d", v.effort, np.float64)
    return out


def _trajectory_point_from_ros(msg: RosJointTrajectoryPoint) -> m.JointTrajectoryPointMsg:
    return m.JointTrajectoryPointMsg(positions=as_numpy(msg.positions, np.float64),
                                     velocities=as_numpy(msg.velocities, np.float64),
                                     accelerations=as_numpy(msg.accelerations, np.float64),
                                     effort=as_numpy(msg.effort, np.float64),
                                     time_from_start=duration_from_ros(msg.time_from_start))


def _trajectory_to_ros(v: m.JointTrajectoryMsg) -> RosJointTrajectory:
    out = RosJointTrajectory(joint_names=list(v.joint_names), points=[_trajectory_point_to_ros(p) for p in v.points])
    header_to_ros(v.header, out.header)
    return out


def _trajectory_from_ros(msg: RosJointTrajectory) -> m.JointTrajectoryMsg:
    return m.JointTrajectoryMsg(joint_names=list(msg.joint_names),
                                points=[_trajectory_point_from_ros(p) for p in msg.points],
                                header=header_from_ros(msg.header))


def _jog_to_ros(v: m.JointJogMsg) -> Any:
    out = ai.JointJog(joint_names=list(v.joint_names), duration=v.duration)
    header_to_ros(v.header, out.header)
    out.displacements = seq("d", v.displacements, np.float64)
    out.velocities = seq("d", v.velocities, np.float64)
    return out


def _jog_from_ros(msg: Any) -> m.JointJogMsg:
    return m.JointJogMsg(joint_names=list(msg.joint_names), displacements=as_numpy(msg.displacements, np.float64),
                         velocities=as_numpy(msg.velocities, np.float64), duration=msg.duration,
                         header=header_from_ros(msg.header))


#: The built-in conversions of this family.
CONVERSIONS: dict[str, RosConversion] = {
    "JointState": RosConversion(RosJointState, _joint_state_to_ros, _joint_state_from_ros),
    "JointTrajectoryPoint": RosConversion(RosJointTrajectoryPoint, _trajectory_point_to_ros,
                                          _trajectory_point_from_ros),
    "JointTrajectory": RosConversion(RosJointTrajectory, _trajectory_to_ros, _trajectory_from_ros),
    "JointJog": RosConversion(ai.JointJog, _jog_to_ros, _jog_from_ros),
}
