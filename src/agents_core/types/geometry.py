"""Geometry: points, poses, velocities (twists), odometry, paths and pose arrays."""

from __future__ import annotations

from typing import Any

from attrs import define, field

from ..errors import TypeValidationError
from ..support.lazy_numpy import is_ndarray, np, npt
from .base import SupportedType
from .fields import Header, Message, header_field, instance_of, is_number, is_str, named, to_array, unstamped, wire

__all__ = [
    "Odometry",
    "OdometryMsg",
    "Path",
    "PathMsg",
    "Point",
    "PointMsg",
    "PointStamped",
    "Pose",
    "PoseArray",
    "PoseArrayMsg",
    "PoseMsg",
    "PoseStamped",
    "Twist",
    "TwistMsg",
]


def _position(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (3,), "position")


def _orientation(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (4,), "orientation")


def _linear(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (3,), "linear")


def _angular(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (3,), "angular")


@named
@define(eq=False)
class PointMsg(Message):
    """A 3-D point."""

    x: float = field(default=0.0, validator=is_number)
    y: float = field(default=0.0, validator=is_number)
    z: float = field(default=0.0, validator=is_number)
    header: Header = header_field()


@named
@define(eq=False)
class PoseMsg(Message):
    """A pose: ``position`` (x, y, z) and ``orientation`` as a quaternion (x, y, z, w)."""

    position: npt.NDArray[np.float64] = field(factory=lambda: np.zeros(3),
                                              converter=_position, metadata=wire("[x, y, z] float", as_list=True))
    orientation: npt.NDArray[np.float64] = field(factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]),
                                                 converter=_orientation,
                                                 metadata=wire("[x, y, z, w] float", as_list=True))
    header: Header = header_field()


@named
@define(eq=False)
class TwistMsg(Message):
    """A velocity: ``linear`` and ``angular`` 3-vectors."""

    linear: npt.NDArray[np.float64] = field(factory=lambda: np.zeros(3),
                                            converter=_linear, metadata=wire("[x, y, z] float", as_list=True))
    angular: npt.NDArray[np.float64] = field(factory=lambda: np.zeros(3),
                                             converter=_angular, metadata=wire("[x, y, z] float", as_list=True))
    header: Header = header_field()


@named
@define(eq=False)
class OdometryMsg(Message):
    """Pose and twist of ``child_frame_id`` in ``header.frame_id``."""

    pose: PoseMsg = field(factory=PoseMsg, validator=instance_of(PoseMsg))
    twist: TwistMsg = field(factory=TwistMsg, validator=instance_of(TwistMsg))
    child_frame_id: str = field(default="", validator=is_str)
    header: Header = header_field()


def _poses(value: Any) -> list[PoseMsg]:
    if not isinstance(value, list | tuple):
        raise TypeValidationError(f"field 'poses': expected a list of PoseMsg, got {type(value).__name__}")
    poses = list(value)
    for i, pose in enumerate(poses):
        if not isinstance(pose, PoseMsg):
            raise TypeValidationError(f"field 'poses[{i}]': expected PoseMsg, got {type(pose).__name__}")
    return poses


@named
@define(eq=False)
class PathMsg(Message):
    """A path: a list of poses, each with its own header (stamp and frame), as ``nav_msgs/Path``."""

    poses: list[PoseMsg] = field(factory=list, converter=_poses)
    header: Header = header_field()


@named
@define(eq=False)
class PoseArrayMsg(Message):
    """Poses in one frame (``header``), as ``geometry_msgs/PoseArray``; the poses' own headers are not sent
    on ROS 2 (they arrive as the array's)."""

    poses: list[PoseMsg] = field(factory=list, converter=_poses)
    header: Header = header_field()


class Point(SupportedType):
    """A 3-D point (:class:`~agents_core.messages.PointMsg`)."""

    value_class = PointMsg

    @classmethod
    def example(cls) -> Any:
        return PointMsg(x=1.0, y=-2.0, z=0.5, header=unstamped())


class PointStamped(Point):
    """A 3-D point whose header matters (stamp and frame)."""

    @classmethod
    def example(cls) -> Any:
        return PointMsg(x=1.0, y=-2.0, z=0.5, header=Header(stamp_ns=1_700_000_000_000_000_007, frame_id="map"))


class Pose(SupportedType):
    """A pose (:class:`~agents_core.messages.PoseMsg`).

    Besides a PoseMsg, an output may be given as upstream's array: ``[x, y, z]`` (no rotation) or
    ``[x, y, z, qw, qx, qy, qz]`` (the quaternion's scalar part first, as upstream; PoseMsg itself
    stores ``[qx, qy, qz, qw]``).
    """

    value_class = PoseMsg

    @classmethod
    def convert(cls, output: Any, frame_id: str | None = None, **_: Any) -> Any:
        """A PoseMsg as it is, or one from upstream's array form (see the class docstring)."""
        if isinstance(output, PoseMsg):
            return output
        if isinstance(output, str | bytes | dict) or not (isinstance(output, list | tuple) or is_ndarray(output)):
            raise TypeValidationError(f"expects PoseMsg or an array [x, y, z(, qw, qx, qy, qz)], "
                                      f"got {type(output).__name__}")
        try:
            values = np.asarray(output, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError) as exc:
            raise TypeValidationError(f"an array pose must hold numbers, got {output!r:.60}") from exc
        if values.size not in (3, 7) or not np.all(np.isfinite(values)):
            raise TypeValidationError(f"an array pose is [x, y, z] or [x, y, z, qw, qx, qy, qz] of finite "
                                      f"numbers, got {values.size} value(s): {output!r:.60}")
        orientation = values[[4, 5, 6, 3]] if values.size == 7 else np.array([0.0, 0.0, 0.0, 1.0])
        header = Header(frame_id=frame_id) if frame_id is not None else Header()
        return PoseMsg(position=values[:3], orientation=orientation, header=header)

    @classmethod
    def example(cls) -> Any:
        return PoseMsg(position=[1, 2, 3], orientation=[0, 0, 0.7071068, 0.7071068], header=unstamped())


class PoseStamped(Pose):
    """A pose whose header matters (stamp and frame)."""

    @classmethod
    def example(cls) -> Any:
        return PoseMsg(position=[1, 2, 3], orientation=[0, 0, 0, 1],
                       header=Header(stamp_ns=1_700_000_000_000_000_009, frame_id="odom"))


class Twist(SupportedType):
    """A velocity command (:class:`~agents_core.messages.TwistMsg`)."""

    value_class = TwistMsg

    @classmethod
    def example(cls) -> Any:
        return TwistMsg(linear=[0.2, 0, 0], angular=[0, 0, 0.5], header=unstamped())


class Odometry(SupportedType):
    """Odometry (:class:`~agents_core.messages.OdometryMsg`)."""

    value_class = OdometryMsg

    @classmethod
    def example(cls) -> Any:
        # Pose and twist share the message's header (nav_msgs/Odometry carries one header).
        stamp, frame = 1_700_000_000_000_000_013, "odom"
        pose = PoseMsg(position=[1, 2, 0], header=Header(stamp_ns=stamp, frame_id=frame))
        twist = TwistMsg(linear=[0.2, 0, 0], header=Header(stamp_ns=stamp, frame_id=frame))
        return OdometryMsg(pose=pose, twist=twist, child_frame_id="base_link",
                           header=Header(stamp_ns=stamp, frame_id=frame))


class Path(SupportedType):
    """A path of stamped poses (:class:`~agents_core.messages.PathMsg`)."""

    value_class = PathMsg

    @classmethod
    def example(cls) -> Any:
        header = Header(stamp_ns=1_700_000_000_000_000_029, frame_id="map")
        poses = [PoseMsg(position=[i, 0.5 * i, 0], header=Header(stamp_ns=header.stamp_ns + i, frame_id="map"))
                 for i in range(3)]
        return PathMsg(poses=poses, header=header)


class PoseArray(SupportedType):
    """Poses in one frame (:class:`~agents_core.messages.PoseArrayMsg`)."""

    value_class = PoseArrayMsg

    @classmethod
    def example(cls) -> Any:
        # geometry_msgs/PoseArray carries one header: the poses share it.
        header = Header(stamp_ns=1_700_000_000_000_000_031, frame_id="base_link")
        poses = [PoseMsg(position=[1, 2, 3], orientation=[0, 0, 0, 1], header=header),
                 PoseMsg(position=[-1, 0, 0.5], orientation=[0, 0, 1, 0], header=header)]
        return PoseArrayMsg(poses=poses, header=header)
