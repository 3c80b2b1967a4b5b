"""Joint limits from a URDF file (standard-library XML only), and the clipping of joint commands to them.

A URDF ``<joint>`` of type ``revolute`` or ``prismatic`` carries ``<limit lower= upper= velocity=
effort=/>``; a ``continuous`` joint has no position limits but may have a velocity limit. Fixed,
floating and planar joints are not commanded and are skipped. The file is size-bounded and may not
declare a DOCTYPE or entities (no entity expansion from a file handed to a robot).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from attrs import define

from ...errors import ConfigError

__all__ = ["JointLimits", "joint_limits_from_config", "read_urdf_joint_limits"]

#: A larger URDF is refused (real robot descriptions are well under a megabyte).
MAX_URDF_BYTES = 16 * 1024 * 1024
_COMMANDED = {"revolute", "prismatic", "continuous"}


@define(frozen=True)
class JointLimits:
    """The limits of one joint: position ``lower``..``upper`` (None: unbounded), ``velocity`` per second
    (None: none)."""

    lower: float | None = None
    upper: float | None = None
    velocity: float | None = None

    def clip_position(self, target: float, current: float | None, dt: float) -> float:
        """``target`` within the position limits and, from ``current``, within ``velocity * dt``."""
        if self.velocity is not None and current is not None and math.isfinite(current):
            reach = self.velocity * dt
            target = min(max(target, current - reach), current + reach)
        if self.lower is not None:
            target = max(target, self.lower)
        if self.upper is not None:
            target = min(target, self.upper)
        return target

    def clip_velocity(self, velocity: float) -> float:
        """``velocity`` within ``±velocity`` limit."""
        if self.velocity is None:
            return velocity
        return min(max(velocity, -self.velocity), self.velocity)


def _number(text: str | None, where: str) -> float | None:
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        raise ConfigError(f"{where}: {text!r} is not a number") from None
    if not math.isfinite(value):
        raise ConfigError(f"{where}: {text!r} is not a finite number")
    return value


def read_urdf_joint_limits(path: str | Path) -> dict[str, JointLimits]:
    """The limits of the commanded joints of the URDF at ``path``, by joint name."""
    p = Path(path)
    try:
        size = p.stat().st_size
        if size > MAX_URDF_BYTES:
            raise ConfigError(f"URDF {p}: {size} bytes, more than the {MAX_URDF_BYTES} allowed")
        data = p.read_bytes()
    except OSError as exc:
        raise ConfigError(f"cannot read URDF {p}: {exc}") from exc
    if b"<!DOCTYPE" in data or b"<!ENTITY" in data:
        raise ConfigError(f"URDF {p}: DOCTYPE and ENTITY declarations are not accepted")
    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        raise ConfigError(f"URDF {p} is not well-formed XML: {exc}") from exc
    if root.tag != "robot":
        raise ConfigError(f"URDF {p}: the root element is <{root.tag}>, expected <robot>")
    limits: dict[str, JointLimits] = {}
    for joint in root.iter("joint"):
        name, kind = joint.get("name"), joint.get("type")
        if not name or kind not in _COMMANDED:
            continue
        where = f"URDF {p} joint {name!r}"
        element = joint.find("limit")
        if element is None:
            if kind != "continuous":
                raise ConfigError(f"{where}: a {kind} joint needs a <limit> element")
            limits[name] = JointLimits()
            continue
        lower = _number(element.get("lower"), f"{where} limit lower")
        upper = _number(element.get("upper"), f"{where} limit upper")
        velocity = _number(element.get("velocity"), f"{where} limit velocity")
        if kind == "continuous":
            lower = upper = None
        else:
            # URDF's defaults for a revolute/prismatic <limit> without them are 0.
            lower = 0.0 if lower is None else lower
            upper = 0.0 if upper is None else upper
        limits[name] = _checked(name, lower, upper, velocity, where)
    return limits


def _checked(name: str, lower: float | None, upper: float | None, velocity: float | None, where: str) -> JointLimits:
    if lower is not None and upper is not None and lower > upper:
        raise ConfigError(f"{where}: lower limit {lower} is above upper limit {upper}")
    if velocity is not None and velocity <= 0:
        # URDF uses velocity="0" for "not given" in some exports; no limit is safer to read as none
        # than as "never move", which would freeze the joint without saying why.
        velocity = None
    return JointLimits(lower, upper, velocity)


def joint_limits_from_config(limits: Mapping[str, Any], owner: str) -> dict[str, JointLimits]:
    """Limits given in a config: joint name -> ``{"lower": .., "upper": .., "velocity": ..}`` (each optional)."""
    out: dict[str, JointLimits] = {}
    for name, spec in limits.items():
        where = f"{owner}.joint_limits[{name!r}]"
        if not isinstance(spec, Mapping):
            raise ConfigError(f"{where} must be a dict with lower / upper / velocity")
        unknown = set(spec) - {"lower", "upper", "velocity"}
        if unknown:
            raise ConfigError(f"{where}: unknown key(s) {sorted(unknown)} (use lower, upper, velocity)")
        values = []
        for key in ("lower", "upper", "velocity"):
            v = spec.get(key)
            if v is not None and (isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v)):
                raise ConfigError(f"{where}: {key} must be a finite number or None, got {v!r}")
            values.append(None if v is None else float(v))
        lower, upper, velocity = values
        if velocity is not None and velocity <= 0:
            raise ConfigError(f"{where}: velocity must be > 0, got {velocity}")
        out[name] = _checked(name, lower, upper, velocity, where)
    return out
