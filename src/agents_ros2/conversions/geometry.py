"""ROS 2 conversions of geometry: ``geometry_msgs`` Point(Stamped), Pose(Stamped), PoseArray, Twist,
and ``nav_msgs`` Odometry and Path.

``geometry_msgs/Point``, ``Pose`` and ``Twist`` have no header: alone they decode with the zero
header; inside a stamped message (Odometry, PoseArray, a map's origin) they take its header.
"""

from __future__ import annotations

from geometry_msgs.msg import Point as RosPoint
from geometry_msgs.msg import PointStamped as RosPointStamped
from geometry_msgs.msg import Pose as RosPose
from geometry_msgs.msg import PoseArray as RosPoseArray
from geometry_msgs.msg import PoseStamped as RosPoseStamped
from geometry_msgs.msg import Twist as RosTwist
from nav_msgs.msg import Odometry as RosOdometry
from nav_msgs.msg import Path as RosPath

from agents_core import messages as m

from .base import RosConversion, header_from_ros, header_to_ros

__all__ = ["CONVERSIONS", "pose_from_ros", "pose_to_ros"]


def _point_to_ros(v: m.PointMsg) -> RosPoint:
    return RosPoint(x=v.x, y=v.y, z=v.z)


# geometry_msgs Point / Pose / Twist carry no header: alone they decode with the zero header (stamp 0,
# no frame), the core's convention for "no stamp"; inside a stamped message they take its header.
def _point_from_ros(msg: RosPoint, header: m.Header | None = None) -> m.PointMsg:
    return m.PointMsg(x=msg.x, y=msg.y, z=msg.z, header=header or m.Header(stamp_ns=0))


def _point_stamped_to_ros(v: m.PointMsg) -> RosPointStamped:
    out = RosPointStamped(point=_point_to_ros(v))
    header_to_ros(v.header, out.header)
    return out


def _point_stamped_from_ros(msg: RosPointStamped) -> m.PointMsg:
    return _point_from_ros(msg.point, header_from_ros(msg.header))


def pose_to_ros(v: m.PoseMsg) -> RosPose:
    """A :class:`~agents_core.messages.PoseMsg` as ``geometry_msgs/Pose`` (which has no header)."""
    out = RosPose()
    out.position.x, out.position.y, out.position.z = (float(c) for c in v.position)
    o = out.orientation
    o.x, o.y, o.z, o.w = (float(c) for c in v.orientation)
    return out


def pose_from_ros(msg: RosPose, header: m.Header | None = None) -> m.PoseMsg:
    p, o = msg.position, msg.orientation
    return m.PoseMsg(position=[p.x, p.y, p.z], orientation=[o.x, o.y, o.z, o.w], header=header or m.Header(stamp_ns=0))


def _pose_stamped_to_ros(v: m.PoseMsg) -> RosPoseStamped:
    out = RosPoseStamped(pose=pose_to_ros(v))
    header_to_ros(v.header, out.header)
    return out


def _pose_stamped_from_ros(msg: RosPoseStamped) -> m.PoseMsg:
    return pose_from_ros(msg.pose, header_from_ros(msg.header))


def _twist_to_ros(v: m.TwistMsg) -> RosTwist:
    out = RosTwist()
    out.linear.x, out.linear.y, out.linear.z = (float(c) for c in v.linear)
    out.angular.x, out.angular.y, out.angular.z = (float(c) for c in v.angular)
    return out


def _twist_from_ros(msg: RosTwist, header: m.Header | None = None) -> m.TwistMsg:
    lin, ang = msg.linear, msg.angular
    return m.TwistMsg(linear=[lin.x, lin.y, lin.z], angular=[ang.x, ang.y, ang.z],
                      header=header or m.Header(stamp_ns=0))


def _odometry_to_ros(v: m.OdometryMsg) -> RosOdometry:
    out = RosOdometry(child_frame_id=v.child_frame_id)
    header_to_ros(v.header, out.header)
    out.pose.pose = pose_to_ros(v.pose)
    out.twist.twist = _twist_to_ros(v.twist)
    return out


def _odometry_from_ros(msg: RosOdometry) -> m.OdometryMsg:
    header = header_from_ros(msg.header)
    return m.OdometryMsg(pose=pose_from_ros(msg.pose.pose, header), twist=_twist_from_ros(msg.twist.twist, header),
                         child_frame_id=msg.child_frame_id, header=header)


def _path_to_ros(v: m.PathMsg) -> RosPath:
    out = RosPath(poses=[_pose_stamped_to_ros(p) for p in v.poses])
    header_to_ros(v.header, out.header)
    return out


def _path_from_ros(msg: RosPath) -> m.PathMsg:
    return m.PathMsg(poses=[_pose_stamped_from_ros(p) for p in msg.poses], header=header_from_ros(msg.header))


def _pose_array_to_ros(v: m.PoseArrayMsg) -> RosPoseArray:
    out = RosPoseArray(poses=[pose_to_ros(p) for p in v.poses])
    header_to_ros(v.header, out.header)
    return out


def _pose_array_from_ros(msg: RosPoseArray) -> m.PoseArrayMsg:
    header = header_from_ros(msg.header)
    # geometry_msgs/Pose has no header: each pose takes the array's.
    return m.PoseArrayMsg(poses=[pose_from_ros(p, header) for p in msg.poses], header=header)


#: The built-in conversions of this family.
CONVERSIONS: dict[str, RosConversion] = {
    "Point": RosConversion(RosPoint, _point_to_ros, _point_from_ros),
    "PointStamped": RosConversion(RosPointStamped, _point_stamped_to_ros, _point_stamped_from_ros),
    "Pose": RosConversion(RosPose, pose_to_ros, pose_from_ros),
    "PoseStamped": RosConversion(RosPoseStamped, _pose_stamped_to_ros, _pose_stamped_from_ros),
    "Twist": RosConversion(RosTwist, _twist_to_ros, _twist_from_ros),
    "Odometry": RosConversion(RosOdometry, _odometry_to_ros, _odometry_from_ros),
    "Path": RosConversion(RosPath, _path_to_ros, _path_from_ros),
    "PoseArray": RosConversion(RosPoseArray, _pose_array_to_ros, _pose_array_from_ros),
}
