"""What the Cortex planner may call: tool descriptions, where each call goes, and argument checks.

A :class:`Tool` is one thing the model may name in a tool call:

- ``"action"``: an :class:`~agents_core.actions.Action` the recipe gave the Cortex (its arguments
  are fixed in the Action; the model passes none);
- ``"component_action"``: a component's ``@component_action`` method, named
  ``"<component>.<method>"``, called through the component's ``execute_method`` service;
- ``"goal"``: a goal to an action-server component, named ``"<component>.send_goal"``, its
  parameters the fields of the action type's goal;
- ``"inspect"``: the built-in ``inspect_component`` research tool;
- ``"mcp"``: a tool of an MCP server of ``CortexConfig.mcp_servers`` (``action`` is its
  :class:`~agents_core.mcp.client.McpRemoteTool`), named ``"<server>__<tool>"``.

Arguments a model writes are checked against the tool's JSON schema (:func:`schema_errors`, the
subset tool descriptions use: ``type``, ``properties``, ``required``, ``additionalProperties``,
``items``, ``enum``, ``minimum`` / ``maximum``) before anything is dispatched: a call that names
no tool, or whose arguments do not fit, is refused, never sent.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

from attrs import define, field

from ...transport.goals import ActionType

__all__ = ["INSPECT", "Tool", "ToolBox", "goal_schema", "parse_arguments", "schema_errors"]

#: The name of the built-in research tool.
INSPECT = "inspect_component"

_EMPTY_SCHEMA: dict[str, Any] = {"type": "object", "properties": {}, "required": [], "additionalProperties": False}

_JSON_TYPES: dict[str, tuple[type, ...]] = {
    "string": (str,), "boolean": (bool,), "integer": (int,), "number": (int, float), "array": (list, tuple),
    "object": (dict,), "null": (type(None),),
}

_GOAL_KINDS: dict[str, dict[str, Any]] = {
    "str": {"type": "string"}, "bool": {"type": "boolean"}, "int": {"type": "integer"},
               "float": {"type": "number"}, "list[float]": {"type": "array", "items": {"type": "number"}},
               "list[int]": {"type": "array", "items": {"type": "integer"}},
               "list[str]": {"type": "array", "items": {"type": "string"}}}


@define(kw_only=True)
class Tool:
    """One callable thing offered to the model (see the module docstring for the kinds)."""

    name: str
    kind: str
    description: str
    parameters: dict[str, Any] = field(factory=lambda: dict(_EMPTY_SCHEMA))
    #: The component it acts on (None: none, e.g. a plain-function Action).
    component: str | None = None
    #: The method (component_action) or the action type name (goal).
    target: str = ""
    #: Used while planning (research) rather than as a plan step.
    planning: bool = False
    #: The Action object, for kind "action".
    action: Any = None

    def openai(self) -> dict[str, Any]:
        """The OpenAI-style description sent to the model."""
        return {"type": "function", "function": {"name": self.name, "description": self.description,
                                                 "parameters": self.parameters}}


def _type_ok(value: Any, expected: str) -> bool:
    if expected in ("integer", "number") and isinstance(value, bool):
        return False
    if expected == "integer" and isinstance(value, float):
        return value.is_integer()
    if expected == "number" and isinstance(value, float) and not math.isfinite(value):
        return False
    return isinstance(value, _JSON_TYPES.get(expected, (object,)))


def schema_errors(schema: Mapping[str, Any], value: Any, where: str = "arguments") -> list[str]:
    """What is wrong with ``value`` under ``schema`` (an empty list: it fits)."""
    errors: list[str] = []
    expected = schema.get("type")
    if isinstance(expected, str) and not _type_ok(value, expected):
        return [f"{where} must be of type {expected}, got {type(value).__name__}"]
    if isinstance(expected, list) and not any(_type_ok(value, t) for t in expected if isinstance(t, str)):
        return [f"{where} must be one of the types {expected}, got {type(value).__name__}"]
    if "enum" in schema and value not in schema["enum"]:
        errors.append(f"{where} must be one of {schema['enum']}, got {value!r}")
    if isinstance(value, int | float) and not isinstance(value, bool):
        if "minimum" in schema and value < schema["minimum"]:
            errors.append(f"{where} must be >= {schema['minimum']}, got {value}")
        if "maximum" in schema and value > schema["maximum"]:
            errors.append(f"{where} must be <= {schema['maximum']}, got {value}")
    if isinstance(value, dict):
        properties = schema.get("properties") or {}
        for name in schema.get("required") or []:
            if name not in value:
                errors.append(f"{where} lacks the required field {name!r}")
        for name, item in value.items():
            if name in properties:
                errors.extend(schema_errors(properties[name], item, f"{where}.{name}"))
            elif isinstance(schema.get("additionalProperties"), Mapping):
                errors.extend(schema_errors(schema["additionalProperties"], item, f"{where}.{name}"))
            elif schema.get("additionalProperties") is not True and ("properties" in schema or where == "arguments"):
                # A field the tool does not declare is a field the model invented: refused, not dropped
                # (an empty ``properties`` declares none: every field is refused).
                errors.append(f"{where} has the unknown field {name!r} (known: {sorted(properties)})")
    if isinstance(value, list | tuple) and isinstance(schema.get("items"), Mapping):
        for i, item in enumerate(value):
            errors.extend(schema_errors(schema["items"], item, f"{where}[{i}]"))
    return errors


def parse_arguments(arguments: Any) -> dict[str, Any]:
    """A tool call's arguments as a dict (a JSON string is parsed); ValueError when they are not an object."""
    if arguments is None or arguments == "":
        return {}
    if isinstance(arguments, str):
        try:
            arguments = json.loads(arguments)
        except json.JSONDecodeError as exc:
            raise ValueError(f"the arguments are not JSON: {exc}") from exc
    if not isinstance(arguments, dict):
        raise ValueError(f"the arguments must be a JSON object, got {type(arguments).__name__}")
    return dict(arguments)


def goal_schema(definition: ActionType) -> dict[str, Any]:
    """The JSON schema of an action type's goal (every field optional: the type has defaults)."""
    properties: dict[str, Any] = {}
    for name, spec in definition.goal.items():
        entry: dict[str, Any] = {**_GOAL_KINDS[spec.kind]}
        if spec.minimum is not None:
            entry["minimum"] = spec.minimum
        if spec.maximum is not None:
            entry["maximum"] = spec.maximum
        properties[name] = entry
    return {"type": "object", "properties": properties, "required": [], "additionalProperties": False}


class ToolBox:
    """The tools of one Cortex, by name (planning and execution phases)."""

    def __init__(self) -> None:
        self._tools: dict[str, Tool] = {}

    def add(self, tool: Tool, *, replace: bool = False) -> bool:
        """Add ``tool``; False (and nothing changes) when its name is taken and ``replace`` is off."""
        if tool.name in self._tools and not replace:
            return False
        self._tools[tool.name] = tool
        return True

    def remove_where(self, condition: Any) -> None:
        """Remove every tool for which ``condition(tool)`` is true."""
        self._tools = {n: t for n, t in self._tools.items() if not condition(t)}

    def get(self, name: str) -> Tool | None:
        """The tool called ``name``, or None."""
        return self._tools.get(name)

    def names(self) -> list[str]:
        """Every tool name, in the order they were added."""
        return list(self._tools)

    def of_component(self, component: str) -> list[Tool]:
        """The tools acting on ``component``."""
        return [t for t in self._tools.values() if t.component == component]

    def descriptions(self, *, planning: bool | None = None) -> list[dict[str, Any]]:
        """OpenAI descriptions: every tool (None), the planning ones (True) or the plan-step ones (False)."""
        return [t.openai() for t in self._tools.values() if planning is None or t.planning == planning]

    def check_call(self, call: Mapping[str, Any], *, planning: bool | None = None) -> tuple[Tool, dict[str, Any]]:
        """The tool and the checked arguments of a model's tool call; ValueError saying what is wrong.

        ``planning`` True / False also refuses a tool of the other phase.
        """
        function = call.get("function") if isinstance(call, Mapping) else None
        name = function.get("name") if isinstance(function, Mapping) else None
        if not isinstance(name, str) or not name:
            raise ValueError("a tool call without a tool name")
        tool = self._tools.get(name)
        if tool is None:
            raise ValueError(f"there is no tool named {name!r}")
        if planning is not None and tool.planning != planning:
            phase = "research (planning)" if tool.planning else "plan-step"
            raise ValueError(f"{name!r} is a {phase} tool and cannot be used here")
        assert isinstance(function, Mapping)
        arguments = parse_arguments(function.get("arguments"))
        problems = schema_errors(tool.parameters, arguments)
        if problems:
            raise ValueError(f"tool {name!r}: " + "; ".join(problems))
        return tool, arguments

    def __len__(self) -> int:
        return len(self._tools)

    def __contains__(self, name: object) -> bool:
        return name in self._tools
