"""The arguments of upstream's ``Launcher.add_pkg`` that this launcher takes for porting, and the error for others.

``ros_log_level`` ("debug", "info", "warn" / "warning", "error", "fatal") sets the ``log_level`` of the
package's components' configs, as it set their ROS nodes' level upstream. ``executable_entry_point``
(a ROS 2 executable upstream) has no meaning here and is accepted; ``activate_all_components_on_start``
may only be True (every component is activated at start). Any other name is a ConfigError that names
it and lists what ``add_pkg`` takes, instead of Python's bare TypeError.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from ..errors import ConfigError

if TYPE_CHECKING:
    from ..components.component_base import Component

__all__ = ["ADD_PKG_ARGUMENTS", "AddPkgArgumentError", "apply_add_pkg_extras"]

logger = logging.getLogger(__name__)

#: What ``add_pkg`` takes (its own arguments and the upstream ones handled here).
ADD_PKG_ARGUMENTS = ("components", "events_actions", "multiprocessing", "package_name", "ros_log_level",
                     "executable_entry_point", "activate_all_components_on_start")
_LEVELS = {"debug": "debug", "info": "info", "warn": "warning", "warning": "warning", "error": "error",
           "fatal": "error"}


class AddPkgArgumentError(ConfigError, TypeError):
    """An argument ``add_pkg`` does not take (a TypeError too, as Python's own would be)."""


def apply_add_pkg_extras(components: Sequence[Component], others: Mapping[str, Any]) -> None:
    """Apply ``ros_log_level`` to ``components``; accept or refuse the other upstream arguments (see the module)."""
    ros_log_level = others.get("ros_log_level")
    unknown = sorted(set(others) - {"ros_log_level", "executable_entry_point", "activate_all_components_on_start"})
    if unknown:
        raise AddPkgArgumentError(f"add_pkg() got unexpected argument(s) {unknown}; it takes "
                                  f"{', '.join(ADD_PKG_ARGUMENTS)}")
    if others.get("activate_all_components_on_start", True) is not True:
        raise ConfigError("add_pkg(activate_all_components_on_start=False) is not supported: every component is "
                          "activated at start; deactivate one afterwards with component.deactivate() or agentsctl "
                          "components transition NAME deactivate")
    if "executable_entry_point" in others:
        logger.debug("add_pkg(executable_entry_point=...) names a ROS 2 executable upstream; not needed here")
    if ros_log_level is None:
        return
    level = _LEVELS.get(str(getattr(ros_log_level, "name", ros_log_level)).lower()) if isinstance(
        ros_log_level, str) or hasattr(ros_log_level, "name") else None
    if level is None:
        raise ConfigError(f"add_pkg(ros_log_level={ros_log_level!r}): use one of {sorted(_LEVELS)}")
    for component in components:
        component.set_params(log_level=level)  # the config and the component's logger
