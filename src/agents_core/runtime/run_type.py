"""How a component is run: on a timer, on events, or as a server."""

from __future__ import annotations

import enum

from ..errors import ConfigError

__all__ = ["ComponentRunType"]


class ComponentRunType(str, enum.Enum):
    """Derived from the trigger unless given explicitly."""

    TIMED = "Timed"
    EVENT = "Event"
    SERVER = "Server"
    ACTION_SERVER = "ActionServer"

    @classmethod
    def parse(cls, value: ComponentRunType | str) -> ComponentRunType:
        """Accept the enum, its value (``"Server"``) or its name (``"SERVER"``), case-insensitively."""
        if isinstance(value, cls):
            return value
        for member in cls:
            if str(value).lower() in (member.value.lower(), member.name.lower()):
                return member
        raise ConfigError(f"unknown run_type {value!r}; use one of {[m.value for m in cls]}")
