"""Joint limits from a URDF file (standard-library XML only), and the clipping of joint commands to them.

A URDF ``<joint>`` of type ``revolute`` or ``prismatic`` carries ``<limit lower= upper= velocity=
effort=/>``; a ``continuous`` joint has no position limits but may have a velocity limit. Fixed,
floating and planar joints are not commanded and are skipped.

The file is handed to a robot, so it is read defensively: it must be a regular file (not a FIFO or
a device such as ``/dev/zero``) of at most :data:`MAX_URDF_BYTES`, in UTF-8 (the check for a DOCTYPE
or entities, refused so that nothing is expanded, only means something in a known encoding: a
UTF-16 file would hide them), each joint named once, and no negative velocity limit.
"""

from __future__ import annotations

import math
import os
import re
import stat
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
#: The encodings an XML declaration may name: UTF-8 and its subset ASCII.
_UTF8_NAMES = {"utf-8", "utf8", "us-ascii", "ascii"}
_DECLARED_ENCODING = re.compile(r"""^<\?xml[^>]*?\sencoding\s*=\s*["']([^"']*)["']""")


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


def _read_bounded(p: Path) -> bytes:
    """The bytes of the regular file ``p``, at most :data:`MAX_URDF_BYTES` of them (ConfigError otherwise)."""
    try:
        # O_NONBLOCK: opening a FIFO with no writer must not hang (it is then refused as not a regular file).
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise ConfigError(f"cannot read URDF {p}: {exc}") from exc
    try:
        # fstat on the opened file, not stat on the path: the file checked is the file read.
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise ConfigError(f"URDF {p} is not a regular file")
        chunks: list[bytes] = []
        left = MAX_URDF_BYTES + 1  # one byte more than allowed tells a file that is too big (or grows)
        while left > 0:
            chunk = os.read(fd, min(left, 1 << 20))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
    except OSError as exc:
        raise ConfigError(f"cannot read URDF {p}: {exc}") from exc
    finally:
        os.close(fd)
    if left <= 0:
        raise ConfigError(f"URDF {p}: more than the {MAX_URDF_BYTES} bytes allowed")
    return b"".join(chunks)


def _checked_text(p: Path, data: bytes) -> None:
    """Refuse what is not UTF-8, or declares a DOCTYPE or entities (checked on the decoded text)."""
    if b"\0" in data:
        # XML has no NUL characters; they are what a UTF-16/32 file (with or without a BOM) is full of.
        raise ConfigError(f"URDF {p}: not UTF-8 (NUL bytes: UTF-16 or UTF-32?); save it as UTF-8")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"URDF {p}: not UTF-8 ({exc}); save it as UTF-8") from None
    declared = _DECLARED_ENCODING.match(text)
    if declared and declared.group(1).strip().lower() not in _UTF8_NAMES:
        raise ConfigError(f"URDF {p}: declares encoding {declared.group(1)!r}; only UTF-8 is accepted")
    if "<!DOCTYPE" in text or "<!ENTITY" in text:
        raise ConfigError(f"URDF {p}: DOCTYPE and ENTITY declarations are not accepted")


def read_urdf_joint_limits(path: str | Path) -> dict[str, JointLimits]:
    """The limits of the commanded joints of the URDF at ``path``, by joint name.

    Raises :class:`ConfigError` naming the problem for a file that is not a regular UTF-8 file of at
    most :data:`MAX_URDF_BYTES`, declares a DOCTYPE or entities, is not a ``<robot>``, names a joint
    twice, or has a limit that is not a finite number (or a negative velocity).
    """
    p = Path(path)
    data = _read_bounded(p)
    _checked_text(p, data)
    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        raise ConfigError(f"URDF {p} is not well-formed XML: {exc}") from exc
    if root.tag != "robot":
        raise ConfigError(f"URDF {p}: the root element is <{root.tag}>, expected <robot>")
    limits: dict[str, JointLimits] = {}
    named: set[str] = set()
    for joint in root.iter("joint"):
        name, kind = joint.get("name"), joint.get("type")
        if name is not None and name in named:
            # The second would silently replace the first's limits: a typo must not loosen a joint.
            raise ConfigError(f"URDF {p}: joint {name!r} is declared twice")
        if name is not None:
            named.add(name)
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
    if velocity is not None and velocity < 0:
        # Read as "none" (below), a sign typo would lift the joint's speed limit altogether.
        raise ConfigError(f"{where}: limit velocity {velocity} is negative (a speed limit is >= 0)")
    if velocity == 0:
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
