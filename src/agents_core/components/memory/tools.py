"""The retrieval tools of :class:`~agents_core.components.memory.Memory`: JSON-schema descriptions and argument checks.

Each tool is answered by the emem engine's tool of the same name; the schemas here list the
arguments that engine takes, so a language model (or a planner) sees the same contract that
:func:`check_arguments` enforces before anything is dispatched. Times are relative strings
(``"-10m"``, ``"-1h"``, ``"-2d"``) or Unix timestamps; coordinates are metres in the world frame.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ...errors import ComponentError

__all__ = ["TOOL_NAMES", "action_description", "check_arguments", "tool_description"]

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


def check_arguments(name: str, arguments: Mapping[str, Any]) -> dict[str, Any]:
    """``arguments`` of tool ``name`` checked against its schema (None values dropped); ComponentError naming
    the unknown, missing or mistyped argument otherwise."""
    _, properties, required = _TOOLS[name]
    given = {k: v for k, v in arguments.items() if v is not None}
    unknown = sorted(set(given) - set(properties))
    if unknown:
        raise ComponentError(f"{name}: unknown argument(s) {unknown}; it takes {sorted(properties)}")
    missing = [k for k in required if k not in given]
    if missing:
        raise ComponentError(f"{name}: missing required argument(s) {missing}")
    for key, value in given.items():
        spec = properties[key]
        # A time may also be given as a Unix timestamp (a number), as the descriptions say.
        if key in _TIME_KEYS and _CHECKS["number"](value):
            given[key] = str(value)
        elif not _CHECKS[spec["type"]](value):
            raise ComponentError(f"{name}: argument {key!r} must be a {spec['type']}, got {value!r:.80}")
        if "enum" in spec and value not in spec["enum"]:
            raise ComponentError(f"{name}: argument {key!r} must be one of {spec['enum']}, got {value!r}")
    if "layers" in given:
        given["layers"] = list(given["layers"])
    return given
