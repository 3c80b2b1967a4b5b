"""Wiring checks of a component, as pure functions: topic lists, allowed types, trigger -> run type.

A component declares the types it accepts as ``allowed_inputs`` / ``allowed_outputs``::

    {"Required": [Image, [String, Audio]], "Optional": [CompressedImage]}

Each ``Required`` entry needs at least one topic of that type (a list entry: of any of its
types); every topic given must match some entry; subclasses of a listed type match it. Every
error names the component, the topic and what was expected.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from ..errors import ConfigError, WiringError
from ..events import Event
from ..runtime.run_type import ComponentRunType
from ..runtime.worker import MAX_TIMER_RATE_HZ
from ..supported_types import SupportedType
from ..topics import FixedInput, Topic

__all__ = [
    "AllowedTypes",
    "TriggerType",
    "check_topic_list",
    "resolve_run_type",
    "trigger_topics",
    "validate_topics",
]

AllowedTypes = Mapping[str, Sequence[type[SupportedType] | Sequence[type[SupportedType]]]]
TriggerType = Topic | Sequence[Topic] | float | int | Event | None


def _type_label(entry: type[SupportedType] | Sequence[type[SupportedType]]) -> str:
    if isinstance(entry, type):
        return entry.type_name()
    return " or ".join(t.type_name() for t in entry)


def _matches(msg_type: type[SupportedType], entry: type[SupportedType] | Sequence[type[SupportedType]]) -> bool:
    options = [entry] if isinstance(entry, type) else list(entry)
    return any(issubclass(msg_type, t) for t in options)


def check_topic_list(component: str, topics: Sequence[Topic] | None, what: str) -> list[Topic]:
    """``topics`` as a list of distinct Topics (``what``: "inputs" or "outputs"), else WiringError."""
    if topics is None:
        return []
    if isinstance(topics, Topic) or not isinstance(topics, Sequence):
        raise WiringError(f"component {component!r}: {what} must be a list of Topic")
    out = list(topics)
    seen: set[str] = set()
    for t in out:
        if not isinstance(t, Topic):
            raise WiringError(f"component {component!r}: {what} has a {type(t).__name__}, not a Topic")
        if t.name in seen:
            raise WiringError(f"component {component!r}: topic {t.name!r} is listed twice in {what}")
        seen.add(t.name)
    if what == "outputs":
        for t in out:
            if isinstance(t, FixedInput):
                raise WiringError(f"component {component!r}: FixedInput {t.name!r} cannot be an output")
    return out


def validate_topics(component: str, owner_class: str, topics: list[Topic], allowed: AllowedTypes | None,
                    kind: str) -> None:
    """Check ``topics`` against ``allowed`` (None: anything goes); ``kind`` is "input" or "output"."""
    if allowed is None:
        return
    unknown_keys = set(allowed) - {"Required", "Optional"}
    if unknown_keys:
        raise ConfigError(f"{owner_class}.allowed_{kind}s has unknown keys {sorted(unknown_keys)}")
    required = list(allowed.get("Required", []))
    optional = list(allowed.get("Optional", []))
    for entry in required:
        if not any(_matches(t.msg_type, entry) for t in topics):
            raise WiringError(
                f"component {component!r} needs an {kind} topic of type {_type_label(entry)}; "
                f"got {[f'{t.name}: {t.type_name}' for t in topics] or 'none'}"
            )
    for t in topics:
        if not any(_matches(t.msg_type, e) for e in required + optional):
            accepted = ", ".join(_type_label(e) for e in required + optional)
            raise WiringError(
                f"component {component!r}: {kind} topic {t.name!r} has type {t.type_name}, "
                f"which it does not accept (accepted: {accepted})"
            )


def trigger_topics(trigger: TriggerType) -> list[Topic]:
    """The input topics whose arrivals fire steps (none for timed, event and server triggers)."""
    if isinstance(trigger, Topic):
        return [trigger]
    if isinstance(trigger, list | tuple):
        return list(trigger)
    return []


def _derived_run_type(component: str, trigger: Any, input_names: set[str]) -> ComponentRunType:
    if isinstance(trigger, bool):
        raise WiringError(f"component {component!r}: trigger cannot be a bool")
    if isinstance(trigger, int | float):
        if not math.isfinite(trigger) or not 0 < trigger <= MAX_TIMER_RATE_HZ:
            raise WiringError(f"component {component!r}: a timed trigger needs a rate > 0 Hz (finite, at most "
                              f"{MAX_TIMER_RATE_HZ:g} Hz), got {trigger}")
        return ComponentRunType.TIMED
    if isinstance(trigger, Topic):
        if trigger.name not in input_names:
            raise WiringError(f"component {component!r}: trigger topic {trigger.name!r} is not one of its inputs "
                              f"{sorted(input_names)}")
        if isinstance(trigger, FixedInput):
            raise WiringError(f"component {component!r}: FixedInput {trigger.name!r} never changes; it cannot trigger")
        return ComponentRunType.EVENT
    if isinstance(trigger, Event):
        return ComponentRunType.EVENT
    if trigger is None:
        return ComponentRunType.SERVER
    if isinstance(trigger, list | tuple):
        if not trigger:
            raise WiringError(f"component {component!r}: an empty list of trigger topics never fires")
        for t in trigger:
            if not isinstance(t, Topic) or t.name not in input_names:
                raise WiringError(f"component {component!r}: trigger {t!r} is not one of its inputs "
                                  f"{sorted(input_names)}")
        return ComponentRunType.EVENT
    raise WiringError(f"component {component!r}: trigger must be a rate (Hz), a Topic, a list of Topics, "
                      f"an Event or None; got {type(trigger).__name__}")


def resolve_run_type(component: str, trigger: TriggerType, run_type: ComponentRunType | str | None,
                     inputs: Sequence[Topic], server_capable: Callable[[], bool]) -> ComponentRunType:
    """The run type ``trigger`` implies, or the explicit ``run_type`` where that is consistent."""
    derived = _derived_run_type(component, trigger, {t.name for t in inputs})
    if run_type is not None:
        chosen = ComponentRunType.parse(run_type)
        if trigger is None and chosen not in (ComponentRunType.SERVER, ComponentRunType.ACTION_SERVER):
            raise WiringError(f"component {component!r}: trigger=None is only valid for Server or ActionServer "
                              f"components, not {chosen.value}")
        return chosen
    if trigger is None and not server_capable():
        raise WiringError(f"component {component!r}: trigger=None is only valid for server components "
                          "(pass run_type='Server' or give a rate, a topic or an event)")
    return derived
