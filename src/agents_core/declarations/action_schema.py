"""The parameters of a ``@component_action`` as a JSON Schema, from its signature, annotations and docstring.

:func:`action_schema` is the one place that says what an action takes; every tool that shows or offers
actions reads it (through the action's description, :func:`describe_action`): the ``describe``
service, ``agentsctl describe`` / ``call``, the web UI's action forms, the tools an LLM or the Cortex
is given. For::

    @component_action
    def set_word(self, word: str, times: int = 1) -> str:
        \"\"\"Change the word the talker says.

        :param word: the new word
        :param times: how often to say it
        \"\"\"

it gives ``{"type": "object", "properties": {"word": {"type": "string", "description": "the new word"},
"times": {"type": "integer", "default": 1, "description": "how often to say it"}}, "required": ["word"],
"additionalProperties": false}``.

Annotations map to JSON types (``str`` string, ``int`` integer, ``float`` number, ``bool`` boolean,
``list`` / ``tuple`` array with ``items``, ``dict`` object, ``Literal[...]`` enum, ``X | None`` adds
``"null"``); a parameter without a known annotation takes any JSON value. Parameter descriptions
come from ``:param name:`` lines (sphinx style) or an ``Args:`` section (Google style).

:func:`bind_call` is how ``execute_method`` binds a request's arguments: ``{"kwargs": {...}}``, or one
JSON object as the only positional argument whose keys are parameter names (what ``agentsctl call
talker set_word '{"word": "hello"}'`` sends), are passed by name.
"""

from __future__ import annotations

import inspect
import re
import types
import typing
from collections.abc import Callable, Mapping
from typing import Any

from ..errors import ConfigError

__all__ = ["action_schema", "bind_call", "describe_action", "docstring_summary", "parameter_descriptions",
           "parameters_text"]

_SIMPLE: dict[Any, str] = {str: "string", int: "integer", float: "number", bool: "boolean", dict: "object",
                           list: "array", tuple: "array", set: "array", frozenset: "array", type(None): "null",
                           bytes: "string"}
_PARAM_LINE = re.compile(r"^\s*:param\s+(?:[^:]*\s)?(\w+)\s*:\s*(.*)$")
_GOOGLE_LINE = re.compile(r"^\s{2,}(\w+)\s*(?:\([^)]*\))?\s*:\s*(.+)$")


def _type_schema(annotation: Any) -> dict[str, Any]:
    """The JSON Schema of one annotation ({} when nothing is known about it)."""
    if annotation is inspect.Parameter.empty or annotation is Any:
        return {}
    if annotation in _SIMPLE:
        return {"type": _SIMPLE[annotation]}
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin is typing.Literal:
        values = [a for a in args if isinstance(a, str | int | float | bool) or a is None]
        return {"enum": values}
    if origin is typing.Union or origin is types.UnionType:
        parts = [_type_schema(a) for a in args]
        others = [p for a, p in zip(args, parts, strict=True) if a is not type(None)]
        if len(others) == 1 and len(parts) == 2 and isinstance(others[0].get("type"), str):
            return {**others[0], "type": [others[0]["type"], "null"]}
        if any(not p or "type" not in p or not isinstance(p["type"], str) for p in parts):
            return {}
        names = list(dict.fromkeys(p["type"] for p in parts))
        return {"type": names[0] if len(names) == 1 else names}
    if origin in (list, tuple, set, frozenset) or origin is typing.Sequence or (
            isinstance(origin, type) and issubclass(origin, list | tuple)):
        schema: dict[str, Any] = {"type": "array"}
        items = [a for a in args if a is not Ellipsis]
        if len(set(items)) == 1:
            item = _type_schema(items[0])
            if item:
                schema["items"] = item
        return schema
    if origin in (dict, Mapping) or (isinstance(origin, type) and issubclass(origin, dict)):
        return {"type": "object"}
    if isinstance(annotation, type) and issubclass(annotation, str | int | float):  # an enum's value type, etc.
        for base, name in _SIMPLE.items():
            if isinstance(base, type) and issubclass(annotation, base) and base is not type(None):
                return {"type": name}
    return {}


def parameter_descriptions(doc: str | None) -> dict[str, str]:
    """``{parameter: description}`` from ``:param name: text`` lines or a Google-style ``Args:`` section."""
    found: dict[str, str] = {}
    lines = inspect.cleandoc(doc or "").splitlines()
    in_args = False
    for line in lines:
        match = _PARAM_LINE.match(line)
        if match:
            found[match.group(1)] = match.group(2).strip()
            continue
        if line.strip() in ("Args:", "Arguments:", "Parameters:"):
            in_args = True
            continue
        if in_args:
            google = _GOOGLE_LINE.match(line)
            if google:
                found[google.group(1)] = google.group(2).strip()
            elif line.strip() and not line.startswith(" "):
                in_args = False
    return found


def docstring_summary(doc: str | None) -> str:
    """The first paragraph of a docstring, on one line."""
    first = inspect.cleandoc(doc or "").split("\n\n")[0]
    return " ".join(first.split())


def _hints(func: Callable[..., Any]) -> dict[str, Any]:
    try:
        return typing.get_type_hints(func)
    except Exception:  # an annotation that does not resolve: read them as written
        return dict(getattr(func, "__annotations__", {}))


def _parameters(func: Callable[..., Any]) -> list[inspect.Parameter]:
    params = list(inspect.signature(func).parameters.values())
    if params and params[0].name in ("self", "cls") and not inspect.ismethod(func):
        params = params[1:]
    return params


def action_schema(func: Callable[..., Any]) -> dict[str, Any]:
    """The JSON Schema (an object) of ``func``'s parameters; ``self``, ``*args`` and ``**kwargs`` left out.

    Each property has the annotation's ``type`` (see the module docstring), its ``default`` when the
    default is a JSON value, and its ``description`` from the docstring; ``required`` lists the
    parameters without a default. ``additionalProperties`` is False unless ``func`` takes ``**kwargs``.
    """
    hints = _hints(func)
    described = parameter_descriptions(func.__doc__)
    properties: dict[str, Any] = {}
    required: list[str] = []
    open_ended = False
    for param in _parameters(func):
        if param.kind is param.VAR_KEYWORD:
            open_ended = True
            continue
        if param.kind is param.VAR_POSITIONAL:
            continue
        entry = dict(_type_schema(hints.get(param.name, param.annotation)))
        if param.default is param.empty:
            required.append(param.name)
        elif param.default is None or isinstance(param.default, str | int | float | bool):
            entry["default"] = param.default
            if param.default is None and "type" in entry and entry["type"] != "null":
                kinds = entry["type"] if isinstance(entry["type"], list) else [entry["type"]]
                entry["type"] = kinds if "null" in kinds else [*kinds, "null"]
        if param.name in described:
            entry["description"] = described[param.name]
        properties[param.name] = entry
    schema: dict[str, Any] = {"type": "object", "properties": properties, "required": required}
    if not open_ended:
        schema["additionalProperties"] = False
    return schema


def describe_action(func: Callable[..., Any], description: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The OpenAI-style tool description of an action: ``{"type": "function", "function": {"name",
    "description", "parameters"}}``; ``description`` (what ``@component_action(description=...)`` was
    given) overrides, and its ``parameters`` default to :func:`action_schema`."""
    if description is not None and "function" in description:
        return dict(description)
    given = dict(description or {})
    function = {"name": func.__name__, "description": docstring_summary(func.__doc__), **given}
    if "parameters" not in function:
        function["parameters"] = action_schema(func)
    return {"type": "function", "function": function}


def parameters_text(description: Any) -> str:
    """An action's parameters on one line, from its description (``word: string, times: integer = 1``);
    "" when it takes none or the description (from the network) has no readable schema."""
    inner = description.get("function", description) if isinstance(description, Mapping) else None
    schema = inner.get("parameters") if isinstance(inner, Mapping) else None
    properties = schema.get("properties") if isinstance(schema, Mapping) else None
    if not isinstance(schema, Mapping) or not isinstance(properties, Mapping):
        return ""
    listed = schema.get("required")
    required: list[Any] = listed if isinstance(listed, list) else []
    parts = []
    for name, raw in properties.items():
        spec = raw if isinstance(raw, Mapping) else {}
        kind = spec.get("type", "enum" if "enum" in spec else "any")
        text = f"{name}: {'|'.join(map(str, kind)) if isinstance(kind, list) else kind}"
        if "default" in spec:
            text += f" = {spec['default']!r}"
        elif name not in required:
            text += " (optional)"
        parts.append(text)
    return ", ".join(parts)


def bind_call(func: Callable[..., Any], args: list[Any], kwargs: Mapping[str, Any],
              where: str) -> tuple[list[Any], dict[str, Any]]:
    """The positional and keyword arguments to call ``func`` with; ConfigError naming ``where`` if they don't fit.

    One JSON object as the only argument whose keys are all parameter names (and which holds every
    required one) is taken as the arguments by name, unless the first parameter is itself an object.
    """
    params = [p for p in _parameters(func) if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
    names = {p.name for p in params}
    if len(args) == 1 and not kwargs and isinstance(args[0], dict) and args[0] and set(args[0]) <= names:
        first = action_schema(func)["properties"].get(params[0].name, {}) if params else {}
        required = {p.name for p in params if p.default is p.empty}
        if first.get("type") != "object" and required <= set(args[0]):
            args, kwargs = [], dict(args[0])
    try:
        inspect.signature(func).bind(*args, **kwargs)
    except TypeError as exc:
        shown = ", ".join(f"{p.name}" + ("" if p.default is p.empty else f"={p.default!r}") for p in params)
        raise ConfigError(f"{where}: {exc}; it takes ({shown}), e.g. {{\"kwargs\": {{...}}}} or one JSON object "
                          "of those names") from None
    return list(args), dict(kwargs)
