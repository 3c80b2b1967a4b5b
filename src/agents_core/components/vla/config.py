"""``VLAConfig``: the settings of ``VLA`` (:mod:`agents_core.components.vla.component`), beside it.

Public as ``agents_core.config.VLAConfig`` (re-exported there on first use); importing this module
does not import the component.
"""

from __future__ import annotations

from typing import Any

import attrs
from attrs import define, field

from ... import base_validators
from ...config import AT_CONFIGURE, ModelComponentConfig
from ...errors import ConfigError

__all__ = ["VLAConfig"]


def _topic_names(value: Any) -> Any:
    """``{camera: Topic}`` (upstream's form) or ``{camera: {"name": ...}}`` as ``{camera: topic name}``."""
    if not isinstance(value, dict):
        return value
    return {k: (v.get("name", v) if isinstance(v, dict) else getattr(v, "name", v) if not isinstance(v, str) else v)
            for k, v in value.items()}


def _str_map(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    if not isinstance(value, dict) or not all(isinstance(k, str) and k and isinstance(v, str) and v
                                              for k, v in value.items()):
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must map non-empty str to non-empty str, "
                          f"got {value!r:.200}")


def _optional_limits(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    if value is None:
        return
    from .urdf import joint_limits_from_config  # noqa: PLC0415  # validates each joint's entry

    if not isinstance(value, dict):
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must be None or a dict joint -> limits")
    joint_limits_from_config(value, type(instance).__name__)


@define(kw_only=True)
class VLAConfig(ModelComponentConfig):
    """Settings of the :class:`~agents_core.components.vla.VLA` component.

    :param joint_names_map: the policy's joint (state / action feature) names -> the robot's joint names.
        Every joint the policy commands must be here: an action for any other joint is an error, never sent.
    :param camera_inputs_map: the policy's camera names -> the component's Image / RGBD inputs (their names,
        or the Topic objects, as upstream's recipes write it).
    :param state_input_type: what the policy's state is, from the JointState input: ``"positions"``,
        ``"velocities"`` or ``"efforts"``.
    :param action_output_type: what the policy's actions are: ``"positions"`` (joint targets) or
        ``"velocities"``.
    :param observation_sending_rate: how often (Hz) an observation is sent to the policy during a goal.
    :param action_sending_rate: how often (Hz) a queued action is sent to the robot.
    :param robot_urdf_file: a URDF whose joint limits (position, velocity) clip every command.
    :param joint_limits: limits by robot joint name (``{"lower": .., "upper": .., "velocity": ..}``);
        they override the URDF's for the joints they name.
    :param max_timesteps: a goal ends (succeeded) after this many commands, unless its ``max_steps`` says
        otherwise.
    :param state_timeout: a joint state older than this (s) is stale: the goal aborts with a hold command.
    :param action_wait_timeout: a goal aborts when no action is ready for this long (s).
    :param on_new_goal: a goal arriving while one runs is ``"reject"``-ed, or ``"preempt"``-s the running
        one (which ends canceled, with a hold command, before the new one starts).
    :param aggregation_function: how overlapping chunks combine: ``"latest_only"``, ``"average"``,
        ``"weighted_average"``, ``"conservative"``
        (see :mod:`agents_core.components.vla.action_chunks`); set a callable with ``VLA.set_aggregation_function``.
    """

    joint_names_map: dict[str, str] = field(factory=dict, validator=_str_map)
    camera_inputs_map: dict[str, str] = field(factory=dict, validator=_str_map, converter=_topic_names)
    state_input_type: str = field(default="positions",
                                  validator=base_validators.in_(["positions", "velocities", "efforts"]))
    action_output_type: str = field(default="positions", validator=base_validators.in_(["positions", "velocities"]))
    observation_sending_rate: float = field(default=10.0, validator=base_validators.in_range(0.01, 1000.0))
    action_sending_rate: float = field(default=10.0, validator=base_validators.in_range(0.01, 1000.0))
    robot_urdf_file: str | None = field(default=None, validator=base_validators.optional_str, metadata=AT_CONFIGURE)
    joint_limits: dict[str, dict[str, float]] | None = field(default=None, validator=_optional_limits,
                                                             metadata=AT_CONFIGURE)
    max_timesteps: int = field(default=100, validator=base_validators.in_range(1, 2**32 - 1))
    state_timeout: float = field(default=1.0, validator=base_validators.in_range(0.001, 3600.0))
    action_wait_timeout: float = field(default=5.0, validator=base_validators.in_range(0.01, 3600.0))
    on_new_goal: str = field(default="reject", validator=base_validators.in_(["reject", "preempt"]))
    aggregation_function: str = field(default="weighted_average", validator=base_validators.in_(
        ["latest_only", "average", "weighted_average", "conservative"]))

