"""The retrieval tools of :class:`~agents_core.components.memory.Memory`: JSON-schema descriptions and argument checks.

Each tool is answered by the emem engine's tool of the same name; the schemas here list the
arguments that engine takes, so a language model (or a planner) sees the same contract that
:func:`check_arguments` enforces before anything is dispatched. Times are relative strings
(``"-10m"``, ``"-1h"``, ``"-2d"``) or Unix timestamps; coordinates are metres in the world frame.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from ...errors import ComponentError

__all__ = ["MAX_RESULTS", "MAX_STRING", "TOOL_NAMES", "action_description", "check_arguments", "tool_description"]

_TIME = "a relative time ('-10m', '-1h', '-2d') or a Unix timestamp"


def _s(description: str) -> dict[str, Any]:
    return {"type": "string", "description": description}


def _n(description: str) -> dict[str, Any]:
    return {"type": "number", "description": description}


def _i(description: str) -> dict[str, Any]:
    return {"type": "integer", "description": description}


_N_RESULTS = _i("how many results at most (default 10)")
_LAYER = _s("only this layer (a layer's name is its topic's name); omit for every layer")
_AFTER, _BEFORE = _s(f"only what was observed after this: {_TIME}"), _s(f"only what was observed before this: {_TIME}")
_NEAR = {"near_x": _n("with near_y: only near this x (m)"), "near_y": _n("with near_x: only near this y (m)"),
         "spatial_radius": _n("the radius (m) around near_x, near_y")}

#: name -> (what it does, properties, required)
_TOOLS: dict[str, tuple[str, dict[str, Any], list[str]]] = {
    "semantic_search": (
        "Find remembered observations by meaning, nearest first, with where and when each was made. Results are "
        "the closest matches, not necessarily answers: if none mentions what was asked, it was not observed.",
        {"query": _s("what to look for, in words"), "n_results": _N_RESULTS, "layer": _LAYER,
         "time_after": _AFTER, "time_before": _BEFORE, **_NEAR,
         "episode_id": _s("only observations of this episode")},
        ["query"]),
    "spatial_query": (
        "List what was observed within a radius of a point, with times.",
        {"x": _n("x (m)"), "y": _n("y (m)"), "z": _n("z (m), default 0"),
         "radius": _n("radius (m), default 2"), "layer": _LAYER, "time_after": _AFTER, "time_before": _BEFORE,
         "n_results": _N_RESULTS},
        ["x", "y"]),
    "temporal_query": (
        "List what was observed in a time window (or the last minutes), newest or oldest first.",
        {"time_after": _AFTER, "time_before": _BEFORE, "last_n_minutes": _n("only the last this many minutes"),
         "layer": _LAYER, **_NEAR,
         "order": {"type": "string", "enum": ["newest", "oldest"], "description": "order (default newest)"},
         "n_results": _N_RESULTS},
        []),
    "episode_summary": (
        "Summarise recorded episodes (tasks started and ended with start_episode / end_episode): their "
        "time span and consolidated summary.",
        {"episode_id": _s("this episode"), "task_name": _s("episodes of this name"),
         "last_n": _i("how many of the latest episodes (default 1)")},
        []),
    "get_current_context": (
        "Where the robot is, what was observed around it and recently: a situation report.",
        {"radius": _n("how far around the robot (m), default 3"),
         "include_recent_minutes": _n("how many recent minutes to include, default 5")},
        []),
    "search_gists": (
        "Search the consolidated summaries of past episodes and time windows by meaning (older memory).",
        {"query": _s("what to look for, in words"), "n_results": _N_RESULTS, "time_after": _AFTER,
         "time_before": _BEFORE},
        ["query"]),
    "entity_query": (
        "List the known things (objects, people, places extracted from observations) by name, kind or place.",
        {"name": _s("the entity's name (or part of it)"), "entity_type": _s("its kind, e.g. 'object', 'person'"),
         **_NEAR, "last_seen_after": _s(f"only those seen after: {_TIME}"), "n_results": _N_RESULTS},
        []),
    "locate": (
        "Where something is: the centre and spread of the places where observations matching it were made "
        "(use the x, y to go there).",
        {"concept": _s("what to find, e.g. 'kitchen', 'red cup'"), "n_results": _N_RESULTS, "layer": _LAYER,
         "time_after": _AFTER, "time_before": _BEFORE},
        ["concept"]),
    "recall": (
        "Everything remembered about something: where it was found and what else was observed around there.",
        {"query": _s("what to recall"), "n_results": _N_RESULTS,
         "radius_multiplier": _n("how far around its places to look, as a multiple of their spread (default 1.5)")},
        ["query"]),
    "body_status": (
        "The robot's latest internal state readings (battery, temperature, ...), one per internal-state layer.",
        {"layers": {"type": "array", "items": {"type": "string"}, "description": "only these layers"}},
        []),
}

_TIME_KEYS = frozenset({"time_after", "time_before", "last_seen_after"})

#: The retrieval tools, in the order they are offered.
TOOL_NAMES: tuple[str, ...] = tuple(_TOOLS)


def tool_description(name: str) -> dict[str, Any]:
    """The OpenAI-style description (``{"type": "function", "function": {...}}``) of tool ``name``."""
    text, properties, required = _TOOLS[name]
    return {"type": "function", "function": {"name": name, "description": text, "parameters": {
        "type": "object", "properties": properties, "required": list(required)}}}


def action_description(name: str) -> dict[str, Any]:
    """:func:`tool_description` with the phase Cortex uses tool ``name`` in (upstream's ``ActionPhase``).

    The retrieval tools answer at once and change nothing: a planner calls them while it plans
    (``"planning"``); ``body_status`` also fits as a plan step (``"both"``).
    """
    return {**tool_description(name), "phase": "both" if name == "body_status" else "planning"}


_CHECKS = {"string": lambda v: isinstance(v, str),
           "number": lambda v: isinstance(v, int | float) and not isinstance(v, bool),
           "integer": lambda v: isinstance(v, int) and not isinstance(v, bool),
           "array": lambda v: isinstance(v, list | tuple) and all(isinstance(x, str) for x in v)}

#: The most a count argument (``n_results``, ``last_n``) may ask for.
MAX_RESULTS = 1000
#: The longest string argument (characters), and the most items of an array argument.
MAX_STRING, MAX_ITEMS = 2000, 100
#: The largest magnitude of a coordinate or distance argument (m), and of a duration (minutes).
MAX_METRES, MAX_MINUTES = 1e7, 1e8
#: Arguments that must be > 0 (a distance, a duration or a multiple); the other numbers are coordinates.
_POSITIVE = frozenset({"radius", "spatial_radius", "last_n_minutes", "include_recent_minutes", "radius_multiplier"})


def _bad(name: str, key: str, why: str, value: Any) -> ComponentError:
    return ComponentError(f"{name}: argument {key!r} {why}, got {value!r:.80}")


def _check_text(name: str, key: str, value: str) -> None:
    if len(value) > MAX_STRING:
        raise _bad(name, key, f"must be at most {MAX_STRING} characters ({len(value)} given)", value[:40])
    try:
        value.encode("utf-8")
    except UnicodeEncodeError:
        raise _bad(name, key, "must be valid Unicode text (it holds a lone surrogate)", value) from None


def _check_value(name: str, key: str, spec: dict[str, Any], value: Any) -> Any:
    """``value`` of ``key`` checked (types, finiteness, ranges, sizes); the value to dispatch."""
    if key in _TIME_KEYS and _CHECKS["number"](value):
        if not math.isfinite(value) or abs(value) > 1e11:
            raise _bad(name, key, "must be a finite Unix timestamp", value)
        return str(value)
    if not _CHECKS[spec["type"]](value):
        raise _bad(name, key, f"must be a {spec['type']}", value)
    if "enum" in spec and value not in spec["enum"]:
        raise ComponentError(f"{name}: argument {key!r} must be one of {spec['enum']}, got {value!r:.80}")
    kind = spec["type"]
    if kind == "integer" and not 1 <= value <= MAX_RESULTS:
        raise _bad(name, key, f"must be an integer from 1 to {MAX_RESULTS}", value)
    if kind == "number":
        if not math.isfinite(value):
            raise _bad(name, key, "must be a finite number", value)
        bound = MAX_MINUTES if "minutes" in key else MAX_METRES
        if key in _POSITIVE and not 0 < value <= bound:
            raise _bad(name, key, f"must be > 0 and at most {bound:g}", value)
        if abs(value) > bound:
            raise _bad(name, key, f"must be at most {bound:g} in magnitude", value)
        return float(value)
    if kind == "string":
        _check_text(name, key, value)
        if key in _TIME_KEYS:
            try:
                stamp = float(value)
            except ValueError:
                return value  # a relative time: the engine parses it (its error names the tool)
            if not math.isfinite(stamp):
                raise _bad(name, key, "must be a finite time", value)
    if kind == "array":
        if len(value) > MAX_ITEMS:
            raise _bad(name, key, f"must have at most {MAX_ITEMS} items ({len(value)} given)", value[:3])
        for item in value:
            _check_text(name, key, item)
        return list(value)
    return value


def check_arguments(name: str, arguments: Mapping[str, Any]) -> dict[str, Any]:
    """``arguments`` of tool ``name`` checked against its schema (None values dropped); ComponentError naming
    the unknown, missing, mistyped or out-of-range argument otherwise (NaN, infinities, counts outside
    1..:data:`MAX_RESULTS`, strings over :data:`MAX_STRING` characters or holding lone surrogates)."""
    _, properties, required = _TOOLS[name]
    if not isinstance(arguments, Mapping) or not all(isinstance(k, str) for k in arguments):
        raise ComponentError(f"{name}: the arguments must be an object of named values")
    given = {k: v for k, v in arguments.items() if v is not None}
    unknown = sorted(set(given) - set(properties))
    if unknown:
        raise ComponentError(f"{name}: unknown argument(s) {[u[:40] for u in unknown[:8]]}; "
                             f"it takes {sorted(properties)}")
    missing = [k for k in required if k not in given]
    if missing:
        raise ComponentError(f"{name}: missing required argument(s) {missing}")
    return {key: _check_value(name, key, properties[key], value) for key, value in given.items()}
