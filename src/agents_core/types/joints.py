"""Joint-space robot state and commands: joint states, trajectories and their waypoints, jog commands."""

from __future__ import annotations

from typing import Any

from attrs import define, field

from ..errors import TypeValidationError
from ..support.lazy_numpy import np, npt
from .base import SupportedType
from .fields import FLOATS, Header, Message, empty_f64, header_field, is_number, is_str_list, named, to_array, wire

__all__ = [
    "JointJog",
    "JointJogMsg",
    "JointState",
    "JointStateMsg",
    "JointTrajectory",
    "JointTrajectoryMsg",
    "JointTrajectoryPoint",
    "JointTrajectoryPointMsg",
]


def _position_vector(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (None,), "position")


def _velocity(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (None,), "velocity")


def _effort(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (None,), "effort")


def _positions(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (None,), "positions")


def _velocities(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (None,), "velocities")


def _accelerations(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (None,), "accelerations")


def _displacements(value: Any) -> npt.NDArray[np.float64]:
    return to_array(value, np.float64, (None,), "displacements")


@named
@define(eq=False)
class JointStateMsg(Message):
    """Joint names with positions, velocities and efforts (each empty or one per name)."""

    name: list[str] = field(factory=list, validator=is_str_list)
    position: npt.NDArray[np.float64] = field(factory=empty_f64, converter=_position_vector, metadata=FLOATS)
    velocity: npt.NDArray[np.float64] = field(factory=empty_f64, converter=_velocity, metadata=FLOATS)
    effort: npt.NDArray[np.float64] = field(factory=empty_f64, converter=_effort, metadata=FLOATS)
    header: Header = header_field()

    def __attrs_post_init__(self) -> None:
        for fname in ("position", "velocity", "effort"):
            size = getattr(self, fname).shape[0]
            if size not in (0, len(self.name)):
                raise TypeValidationError(f"field {fname!r}: {size} values for {len(self.name)} joints")


@named
@define(eq=False)
class JointTrajectoryPointMsg(Message):
    """One waypoint of a joint trajectory; ``time_from_start`` in seconds."""

    positions: npt.NDArray[np.float64] = field(factory=empty_f64, converter=_positions, metadata=FLOATS)
    velocities: npt.NDArray[np.float64] = field(factory=empty_f64, converter=_velocities, metadata=FLOATS)
    accelerations: npt.NDArray[np.float64] = field(factory=empty_f64, converter=_accelerations, metadata=FLOATS)
    effort: npt.NDArray[np.float64] = field(factory=empty_f64, converter=_effort, metadata=FLOATS)
    time_from_start: float = field(default=0.0, validator=is_number, metadata=wire("float (s)"))


def _trajectory_points(value: Any) -> list[JointTrajectoryPointMsg]:
    points = list(value)
    for i, p in enumerate(points):
        if not isinstance(p, JointTrajectoryPointMsg):
            raise TypeValidationError(f"field 'points[{i}]': expected JointTrajectoryPointMsg")
    return points


@named
@define(eq=False)
class JointTrajectoryMsg(Message):
    """A trajectory: joint names and a list of waypoints."""

    joint_names: list[str] = field(factory=list, validator=is_str_list)
    points: list[JointTrajectoryPointMsg] = field(factory=list, converter=_trajectory_points)
    header: Header = header_field()


@named
@define(eq=False)
class JointJogMsg(Message):
    """Jog command: per-joint displacements and/or velocities over ``duration`` seconds."""

    joint_names: list[str] = field(factory=list, validator=is_str_list)
    displacements: npt.NDArray[np.float64] = field(factory=empty_f64, converter=_displacements, metadata=FLOATS)
    velocities: npt.NDArray[np.float64] = field(factory=empty_f64, converter=_velocities, metadata=FLOATS)
    duration: float = field(default=0.0, validator=is_number, metadata=wire("float (s)"))
    header: Header = header_field()


class JointState(SupportedType):
    """Joint states (:class:`~agents_core.messages.JointStateMsg`)."""

    value_class = JointStateMsg

    @classmethod
    def example(cls) -> Any:
        return JointStateMsg(name=["shoulder", "elbow"], position=[0.1, 0.2], velocity=[0, 0], effort=[])


class JointTrajectoryPoint(SupportedType):
    """One trajectory waypoint (:class:`~agents_core.messages.JointTrajectoryPointMsg`)."""

    value_class = JointTrajectoryPointMsg

    @classmethod
    def example(cls) -> Any:
        return JointTrajectoryPointMsg(positions=[0.1, 0.2], velocities=[0.0, 0.0], time_from_start=1.5)


class JointTrajectory(SupportedType):
    """A joint trajectory (:class:`~agents_core.messages.JointTrajectoryMsg`)."""

    value_class = JointTrajectoryMsg

    @classmethod
    def example(cls) -> Any:
        return JointTrajectoryMsg(joint_names=["shoulder", "elbow"],
                                  points=[JointTrajectoryPoint.example(), JointTrajectoryPoint.example()])


class JointJog(SupportedType):
    """A jog command (:class:`~agents_core.messages.JointJogMsg`)."""

    value_class = JointJogMsg

    @classmethod
    def example(cls) -> Any:
        return JointJogMsg(joint_names=["wrist"], velocities=[0.3], duration=0.5)
