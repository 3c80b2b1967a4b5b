"""The message types, by family: each value class beside the :class:`~.base.SupportedType` that names it.

- :mod:`.base`: :class:`~.base.SupportedType`, the registry (:func:`~.base.add_additional_datatypes`,
  :func:`~.base.get_type`) and the checks of ROS-message values;
- :mod:`.fields`: :class:`~.fields.Header` and the validators and converters the value classes share;
- the families: :mod:`.text`, :mod:`.scalars`, :mod:`.media`, :mod:`.perception`, :mod:`.geometry`,
  :mod:`.joints`, :mod:`.maps`, :mod:`.sensors`, :mod:`.component_status`.

Users import these names from :mod:`agents_core.messages` (the value classes) and
:mod:`agents_core.supported_types` (the types and the registry), which re-export them.

The built-in types are registered when the registry is first used (a name looked up, the
registry listed, a type added), all of them at once, in :data:`BUILTIN_TYPES` order: codecs, the
schema document and the conformance suite list the types in that order. Importing the package
imports no family module: a relay recipe that names ``String`` does not pay for building the
image, perception and sensor classes. To add a built-in type: put its value class and type in
their family's module, then append ``(name, family)`` to :data:`_BUILTINS`.
"""

from __future__ import annotations

import importlib
import threading
from typing import TYPE_CHECKING, Any

from ..support.lazy import lazy_facade
from . import base
from .base import SupportedType, add_additional_datatypes

#: The framework's own message types, in registration order (the order predates the families:
#: types added later come last, whatever their family), each with its family module.
_BUILTINS: tuple[tuple[str, str], ...] = (
    ("String", "text"), ("StreamingString", "text"), ("Bool", "scalars"), ("Int32", "scalars"),
    ("Int64", "scalars"), ("Float32", "scalars"), ("Float64", "scalars"), ("Float32MultiArray", "scalars"),
    ("Float64MultiArray", "scalars"), ("Image", "media"), ("CompressedImage", "media"), ("Audio", "media"),
    ("Video", "media"), ("Detections", "perception"), ("DetectionsMultiSource", "perception"),
    ("Trackings", "perception"), ("TrackingsMultiSource", "perception"), ("PointsOfInterest", "perception"),
    ("Point", "geometry"), ("PointStamped", "geometry"), ("Pose", "geometry"), ("PoseStamped", "geometry"),
    ("Twist", "geometry"), ("Odometry", "geometry"), ("JointState", "joints"),
    ("JointTrajectoryPoint", "joints"), ("JointTrajectory", "joints"), ("JointJog", "joints"),
    ("OccupancyGrid", "maps"), ("LaserScan", "sensors"), ("ComponentStatus", "component_status"),
    ("RGBD", "media"), ("PointCloud2", "sensors"), ("Imu", "sensors"), ("NavSatFix", "sensors"),
    ("Path", "geometry"), ("PoseArray", "geometry"), ("MapMetaData", "maps"), ("CameraInfo", "sensors"),
)

_builtin_types: tuple[type[SupportedType], ...] | None = None
_builtin_lock = threading.RLock()

#: The framework's own message types, in registration order (imports every family module when read);
#: declared, not assigned, so that the module ``__getattr__`` below answers it.
BUILTIN_TYPES: tuple[type[SupportedType], ...]


def _builtins() -> tuple[type[SupportedType], ...]:
    global _builtin_types  # noqa: PLW0603 - built once, at first use
    if _builtin_types is None:
        with _builtin_lock:
            if _builtin_types is None:
                _builtin_types = tuple(getattr(importlib.import_module(f"{__name__}.{family}"), name)
                                       for name, family in _BUILTINS)
    return _builtin_types


if not TYPE_CHECKING:
    _facade_getattr, __dir__ = lazy_facade(__name__, own=("BUILTIN_TYPES", "is_builtin_type"))

    def __getattr__(name: str) -> Any:
        if name == "BUILTIN_TYPES":
            return _builtins()
        return _facade_getattr(name)


def is_builtin_type(msg_type: type) -> bool:
    """True for the framework's own message types (:data:`BUILTIN_TYPES`), False for user-registered ones."""
    return msg_type in _builtins()


def _register_builtins() -> None:
    add_additional_datatypes(_builtins())


base.install_builtin_types(_register_builtins)
