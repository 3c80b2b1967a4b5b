"""What a recipe offers over MCP: its actions as tools, its topics and health as resources.

The catalog reads a running recipe the way every outside tool does: through a transport, each
component's ``<name>/describe`` reply (:class:`~agents_core.ui.recipe_view.RemoteRecipe`). A tool
is named ``<component>__<action>``; its input schema is the action's parameter schema (from the
signature, annotations and docstring, with guardrail limits as ``minimum`` / ``maximum``) and its
description the docstring's summary. Calling it sends ``<component>/execute_method`` with the
caller ``"mcp"``, so the action's guardrails run in the component's own process, for this caller
as for every other.

Resources: ``agents://recipe`` (every component's description), ``agents://health`` (state and
health of each) and ``agents://topic/<topic name>`` (the latest value of each output topic).
"""

from __future__ import annotations

import fnmatch
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from attrs import define

from ..errors import AgentsError, ConfigError

if TYPE_CHECKING:
    from ..transport.contract import Transport

__all__ = ["TOOL_SEPARATOR", "McpTool", "RecipeCatalog", "tool_name"]

#: Between the component's and the action's name in a tool's name (``arm__move``).
TOOL_SEPARATOR = "__"
#: MCP tool names: letters, digits, ``_``, ``-`` and ``.``, up to 128 characters.
_TOOL_NAME = re.compile(r"^[A-Za-z0-9_.\-]{1,128}$")


def tool_name(component: str, action: str) -> str:
    """The MCP tool name of ``component``'s ``action``."""
    return f"{component}{TOOL_SEPARATOR}{action}"


@define(frozen=True)
class McpTool:
    """One action (or, with ``goal_type``, an action server's goal) offered as an MCP tool."""

    name: str
    component: str
    action: str
    description: str
    input_schema: dict[str, Any]
    guardrails: dict[str, Any]
    goal_type: str | None = None


#: The tool name's action part for an action server's goals (``vla__goal``).
GOAL_ACTION = "goal"
_KIND_SCHEMA: dict[str, dict[str, Any]] = {
    "str": {"type": "string"}, "bool": {"type": "boolean"}, "int": {"type": "integer"},
    "float": {"type": "number"}, "list[float]": {"type": "array", "items": {"type": "number"}},
    "list[int]": {"type": "array", "items": {"type": "integer"}},
    "list[str]": {"type": "array", "items": {"type": "string"}}}


def goal_schema(type_name: str) -> dict[str, Any] | None:
    """The JSON Schema of a registered action type's goal (None: no such type here)."""
    from ..transport.goals import action_type  # noqa: PLC0415

    try:
        definition = action_type(type_name)
    except (AgentsError, KeyError):
        return None
    properties: dict[str, Any] = {}
    for name, spec in definition.goal.items():
        entry = dict(_KIND_SCHEMA.get(spec.kind, {}))
        entry["default"] = spec.default_value()
        if spec.minimum is not None:
            entry["minimum"] = spec.minimum
        if spec.maximum is not None:
            entry["maximum"] = spec.maximum
        properties[name] = entry
    return {"type": "object", "properties": properties, "required": [], "additionalProperties": False}


def _schema_of(description: Any) -> dict[str, Any]:
    function = description.get("function", description) if isinstance(description, Mapping) else {}
    schema = function.get("parameters") if isinstance(function, Mapping) else None
    if not isinstance(schema, Mapping) or schema.get("type") != "object":
        # Nothing known about the parameters: an object with no properties, and no others accepted.
        return {"type": "object", "properties": {}, "additionalProperties": False}
    return dict(schema)


def _summary_of(description: Any) -> str:
    function = description.get("function", description) if isinstance(description, Mapping) else {}
    text = function.get("description") if isinstance(function, Mapping) else None
    return str(text)[:2000] if isinstance(text, str) else ""


class RecipeCatalog:
    """The tools and resources of the recipe that ``transport`` reaches.

    :param components: the components to offer (None: every component discovered).
    :param allow: glob patterns of the tool names MCP may offer at all (None: every action);
        a tool not allowed is neither listed nor callable.
    :param timeout: seconds for each discovery and describe request.
    """

    def __init__(self, transport: Transport, *, components: Iterable[str] | None = None,
                 allow: Sequence[str] | None = None, timeout: float = 2.0) -> None:
        from ..ui.recipe_view import RemoteRecipe  # noqa: PLC0415

        if allow is not None and (isinstance(allow, str) or not all(isinstance(p, str) for p in allow)):
            raise ConfigError(f"MCP allow must be a list of tool name patterns, got {allow!r}")
        self.transport = transport
        self._view = RemoteRecipe(transport, components, timeout=timeout)
        self._allow = list(allow) if allow is not None else None
        self._timeout = timeout

    def allowed(self, name: str) -> bool:
        """Whether the allow-list lets MCP offer the tool ``name``."""
        return self._allow is None or any(fnmatch.fnmatchcase(name, p) for p in self._allow)

    def descriptions(self) -> dict[str, dict[str, Any]]:
        """Each reachable component's describe reply (one that does not answer is left out)."""
        found: dict[str, dict[str, Any]] = {}
        for name in self._view.component_names():
            try:
                found[name] = self._view.describe(name)
            except (AgentsError, KeyError):
                continue
        return found

    def tools(self) -> list[McpTool]:
        """The actions offered, sorted by tool name."""
        tools: list[McpTool] = []
        for component, reply in self.descriptions().items():
            actions = reply.get("actions")
            given = reply.get("guardrails")
            guardrails: dict[str, Any] = given if isinstance(given, dict) else {}
            if not isinstance(actions, Mapping):
                continue
            for action, description in actions.items():
                name = tool_name(component, str(action))
                if not _TOOL_NAME.match(name) or not self.allowed(name):
                    continue
                found = guardrails.get(action)
                guard: dict[str, Any] = found if isinstance(found, dict) else {}
                tools.append(McpTool(name, component, str(action), _summary_of(description),
                                     _schema_of(description), dict(guard)))
            kind = reply.get("action_type")
            name = tool_name(component, GOAL_ACTION)
            if isinstance(kind, str) and GOAL_ACTION not in actions and self.allowed(name) and _TOOL_NAME.match(name):
                schema = goal_schema(kind)
                if schema is not None:
                    tools.append(McpTool(name, component, GOAL_ACTION,
                                         f"Send {component} a {kind} goal; reports its feedback as progress and "
                                         "stops it when the call is cancelled.", schema, {}, goal_type=kind))
        return sorted(tools, key=lambda t: t.name)

    def find(self, name: str) -> McpTool:
        """The tool ``name``; ConfigError naming the tools there are when there is no such (allowed) tool."""
        if not isinstance(name, str) or not self.allowed(name) or TOOL_SEPARATOR not in name:
            raise ConfigError(f"no MCP tool {str(name)[:200]!r}")
        for tool in self.tools():
            if tool.name == name:
                return tool
        raise ConfigError(f"no MCP tool {name[:200]!r}; there are {[t.name for t in self.tools()][:50]}")

    def call(self, tool: McpTool, arguments: Mapping[str, Any] | None, *, timeout: float,
             call_id: str | None = None, approval_timeout: float | None = None) -> Any:
        """Run ``tool`` with ``arguments`` (checked against its schema first) in its component; its result."""
        arguments = dict(arguments or {})
        check_arguments(tool, arguments)
        payload: dict[str, Any] = {"method": tool.action, "kwargs": arguments, "timeout": timeout, "caller": "mcp"}
        if call_id is not None:
            payload["call_id"] = call_id
        if approval_timeout is not None:
            payload["approval_timeout"] = approval_timeout
        reply = self.transport.request(f"{tool.component}/execute_method", payload, timeout=timeout + 1.0)
        return reply.get("result") if isinstance(reply, dict) else reply

    def state(self, component: str) -> str:
        """``component``'s lifecycle state now ("unreachable" when it does not answer)."""
        try:
            reply = self._view.describe(component)
        except (AgentsError, KeyError):
            return "unreachable"
        return str(reply.get("state"))

    def health(self) -> dict[str, dict[str, Any]]:
        """``{component: {"state", "health"}}`` of each reachable component."""
        return {name: {"state": reply.get("state"), "health": reply.get("health")}
                for name, reply in self.descriptions().items()}

    def output_topics(self) -> dict[str, str]:
        """``{topic name: type name}`` of every component's outputs."""
        found: dict[str, str] = {}
        for reply in self.descriptions().values():
            for entry in reply.get("outputs", []):
                found.setdefault(entry["name"], entry["msg_type"])
        return found


_JSON_TYPES: dict[str, tuple[type, ...]] = {"string": (str,), "integer": (int,), "number": (int, float),
                                            "boolean": (bool,), "array": (list,), "object": (dict,),
                                            "null": (type(None),)}


def _fits(value: Any, kind: str) -> bool:
    if kind in ("integer", "number") and isinstance(value, bool):
        return False
    return isinstance(value, _JSON_TYPES.get(kind, (object,)))


def check_arguments(tool: McpTool, arguments: Mapping[str, Any]) -> None:
    """Refuse arguments the tool's schema does not take: unknown names, missing ones, wrong JSON types,
    numbers outside ``minimum`` / ``maximum`` (NaN included). The component checks again (its guardrails)."""
    schema = tool.input_schema
    given = schema.get("properties")
    properties: Mapping[str, Any] = given if isinstance(given, Mapping) else {}
    unknown = sorted(k for k in arguments if k not in properties)
    if unknown and schema.get("additionalProperties") is not True:
        raise ConfigError(f"tool {tool.name!r}: unknown argument(s) {unknown[:20]}; it takes {sorted(properties)}")
    listed = schema.get("required")
    required: list[Any] = listed if isinstance(listed, list) else []
    missing = [k for k in required if k not in arguments]
    if missing:
        raise ConfigError(f"tool {tool.name!r}: missing argument(s) {missing}")
    for key, value in arguments.items():
        spec = properties.get(key)
        if not isinstance(spec, Mapping):
            continue
        kinds = spec.get("type")
        kinds = [kinds] if isinstance(kinds, str) else kinds if isinstance(kinds, list) else None
        if kinds and not any(_fits(value, k) for k in kinds):
            raise ConfigError(f"tool {tool.name!r}: argument {key!r} must be {' or '.join(kinds)}, "
                              f"got {type(value).__name__}")
        if "enum" in spec and isinstance(spec["enum"], list) and value not in spec["enum"]:
            raise ConfigError(f"tool {tool.name!r}: argument {key!r} must be one of {spec['enum'][:20]}")
        items = spec.get("items")
        bounds: Mapping[str, Any] = items if isinstance(value, list) and isinstance(items, Mapping) else spec
        for item in value if isinstance(value, list) else [value]:
            if isinstance(item, bool) or not isinstance(item, int | float):
                continue
            low, high = bounds.get("minimum"), bounds.get("maximum")
            if not math.isfinite(float(item)) or (isinstance(low, int | float) and item < low) or (
                    isinstance(high, int | float) and item > high):
                raise ConfigError(f"tool {tool.name!r}: argument {key!r} = {item!r} is outside "
                                  f"[{low}, {high}]; the action did not run")
