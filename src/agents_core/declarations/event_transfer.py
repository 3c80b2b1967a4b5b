"""Events as data, so that a component in its own process can watch an event the recipe built.

An :class:`~agents_core.events.Event` on a topic (``Event(topic)``) or on a condition built from
field references (``Event(topic.msg.data > 0.5)``, combined with ``&``, ``|``, ``~``) is sent to a
component process as its name, its options and the recipe of its condition
(:attr:`Condition.recipe <agents_core.conditions.Condition.recipe>`); the process builds the same
event again and the component subscribes to its topics there (the VLA's termination event). An
event with no topic (fired by code with :meth:`Event.trigger`) or with a condition made from a
function cannot be rebuilt: :func:`encode_event` refuses it with a ConfigError that says why.

A component *triggered* by an event does not go through here: the launcher evaluates that one and
forwards its firings (:class:`agents_core.launch.spec.LauncherEvent`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ..conditions import Condition, FieldRef
from ..errors import ConfigError
from ..events import Event
from ..topics import Topic

__all__ = ["decode_event", "encode_event"]

#: The FieldRef method that builds each comparison symbol of a recipe (``"is"`` depends on its value).
_BUILDERS: dict[str, Callable[[FieldRef, Any], Condition]] = {
    "==": lambda ref, v: ref == v,
    "!=": lambda ref, v: ref != v,
    "<": lambda ref, v: ref < v,
    "<=": lambda ref, v: ref <= v,
    ">": lambda ref, v: ref > v,
    ">=": lambda ref, v: ref >= v,
    "in": lambda ref, v: ref.is_in(v),
    "not in": lambda ref, v: ref.not_in(v),
    "contains": lambda ref, v: ref.contains(v),
    "not contains": lambda ref, v: ref.not_contains(v),
    "contains any of": lambda ref, v: ref.contains_any(v),
    "contains all of": lambda ref, v: ref.contains_all(v),
    "contains none of": lambda ref, v: ref.not_contains_any(v),
    "misses one of": lambda ref, v: ref.not_contains_all(v),
    "is": lambda ref, v: ref.is_true() if v else ref.is_false(),
}


def _cannot(event: Event, why: str) -> ConfigError:
    return ConfigError(f"event {event.name!r} {why}, so a component in its own process cannot watch it; give "
                       "the event a condition on a topic (Event(topic) or Event(topic.msg.data > 0.5)), or run "
                       "the component with multiprocessing=False")


def _encode_recipe(recipe: tuple[Any, ...], encode: Callable[[Any, str], Any]) -> list[Any]:
    kind = recipe[0]
    if kind == "compare":
        _, topic, path, symbol, value = recipe
        return [kind, encode(topic, "topic"), list(path), symbol, encode(value, "value")]
    return [kind, *(_encode_recipe(part, encode) for part in recipe[1:])]


def _decode_recipe(data: list[Any], decode: Callable[[Any], Any]) -> Condition:
    kind = data[0] if isinstance(data, list) and data else None
    if kind == "compare" and len(data) == 5:
        topic = decode(data[1])
        if not isinstance(topic, Topic) or not isinstance(data[2], list) or data[3] not in _BUILDERS:
            raise ConfigError(f"event condition: a malformed comparison {data!r}")
        return _BUILDERS[data[3]](FieldRef(topic, tuple(data[2])), decode(data[4]))
    if kind in ("and", "or") and len(data) == 3:
        a, b = _decode_recipe(data[1], decode), _decode_recipe(data[2], decode)
        return a & b if kind == "and" else a | b
    if kind == "not" and len(data) == 2:
        return ~_decode_recipe(data[1], decode)
    raise ConfigError(f"event condition: unknown recipe {data!r}")


def encode_event(event: Event) -> dict[str, Any]:
    """``event`` as JSON-like data (topics and values through the process codecs of :mod:`agents_core.launch.spec`)."""
    from ..launch.spec import encode_value  # noqa: PLC0415  # the codecs live there; spec imports this module

    where = f"event {event.name!r}"
    cond = event.event_condition
    if cond is None:
        raise _cannot(event, "has no topic (it fires only when code calls trigger() in the launcher's process)")
    if isinstance(cond, Topic):
        condition: Any = {"topic": encode_value(cond, where)}
    else:
        if cond.recipe is None:
            raise _cannot(event, f"has a condition made from a function ({cond.description})")
        condition = {"recipe": _encode_recipe(cond.recipe, lambda v, what: encode_value(v, f"{where}: {what}"))}
    return {"name": event.name, "condition": condition, "on_change": event.on_change,
            "handle_once": event.handle_once, "keep_event_delay": event.keep_event_delay}


def decode_event(data: dict[str, Any]) -> Event:
    """The event :func:`encode_event` encoded (a new object with the same name, condition and options)."""
    from ..launch.spec import decode_value  # noqa: PLC0415

    condition = data.get("condition")
    if not isinstance(condition, dict):
        raise ConfigError(f"event {data.get('name')!r}: a malformed condition")
    built: Topic | Condition
    if "topic" in condition:
        topic = decode_value(condition["topic"])
        if not isinstance(topic, Topic):
            raise ConfigError(f"event {data.get('name')!r}: a malformed topic")
        built = topic
    else:
        built = _decode_recipe(condition.get("recipe"), decode_value)  # type: ignore[arg-type]
    return Event(str(data["name"]), built, on_change=bool(data.get("on_change")),
                 handle_once=bool(data.get("handle_once")),
                 keep_event_delay=float(data.get("keep_event_delay") or 0.0))
