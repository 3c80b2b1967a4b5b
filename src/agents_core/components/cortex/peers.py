"""What Cortex believes about its peers: describe replies checked, the component allow-list, results as data.

Any process on the transport can answer a ``<name>/describe`` request, so a reply is untrusted
input: :func:`checked_description` accepts only the shape ``describe_component`` documents
(strings where strings belong, lists of ``{"name", "msg_type"}``, an ``actions`` map of bounded
size whose entries are objects) and refuses anything else with one :class:`DescribeRefused`
naming the component and the field, so a malformed reply leaves that component out instead of
aborting the task with a raw ``AttributeError``.

:func:`allowed` applies ``CortexConfig.allowed_components``: None (the default) means the
components of Cortex's own recipe (the Launcher tells it their names), ``["*"]`` any component
the transport shows. :func:`as_data` wraps what a tool or a topic returned before the planner or
the confirmation model reads it: a block naming its source, its text escaped so it cannot close
the block early. The prompts say that such blocks are data, never instructions.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Any

from ...errors import RemoteError

__all__ = ["ANY_COMPONENT", "DescribeRefused", "allowed", "as_data", "checked_description"]

#: ``allowed_components=["*"]``: every component the transport shows (an explicit opt-in).
ANY_COMPONENT = "*"
#: The most actions one component may describe (more is a hostile or broken reply).
MAX_ACTIONS = 256
_METHOD = re.compile(r"^[A-Za-z_][A-Za-z0-9_]{0,127}$")
_STRINGS = ("name", "component_type", "run_type", "state", "health")


class DescribeRefused(RemoteError):
    """A component's describe reply does not have the documented shape."""


def _refuse(name: str, why: str) -> DescribeRefused:
    return DescribeRefused(f"component {name!r} sent a malformed describe reply: {why}; its actions are not offered")


def _topics(name: str, field: str, value: Any) -> list[dict[str, str]]:
    if not isinstance(value, list) or len(value) > 10_000:
        raise _refuse(name, f"{field!r} must be a list of topics")
    out = []
    for i, item in enumerate(value):
        if not (isinstance(item, dict) and isinstance(item.get("name"), str) and isinstance(item.get("msg_type"), str)):
            raise _refuse(name, f"{field}[{i}] must be {{'name': str, 'msg_type': str}}")
        out.append({"name": item["name"][:500], "msg_type": item["msg_type"][:200]})
    return out


def _action(name: str, method: Any, raw: Any) -> dict[str, Any]:
    if not isinstance(method, str) or not _METHOD.match(method):
        raise _refuse(name, f"action name {str(method)[:80]!r} is not a method name")
    if not isinstance(raw, dict):
        raise _refuse(name, f"action {method!r} must be an object, got {type(raw).__name__}")
    function = raw.get("function", raw)
    if not isinstance(function, dict):
        raise _refuse(name, f"action {method!r}: 'function' must be an object")
    description = function.get("description", method)
    parameters = function.get("parameters", {"type": "object", "properties": {}})
    if not isinstance(description, str):
        raise _refuse(name, f"action {method!r}: 'description' must be a string")
    if not isinstance(parameters, dict) or not isinstance(parameters.get("properties", {}), dict):
        raise _refuse(name, f"action {method!r}: 'parameters' must be a JSON schema object")
    phase = raw.get("phase") or function.get("phase")
    if phase is not None and phase not in ("planning", "execution", "both"):
        raise _refuse(name, f"action {method!r}: 'phase' must be 'planning', 'execution' or 'both'")
    return {"function": {"description": description[:2000], "parameters": parameters}, "phase": phase}


def checked_description(name: str, reply: Any) -> dict[str, Any]:
    """``reply`` if it is a well-formed describe reply of component ``name``, else :class:`DescribeRefused`."""
    if not isinstance(reply, dict):
        raise _refuse(name, f"expected an object, got {type(reply).__name__}")
    for field in _STRINGS:
        if not isinstance(reply.get(field), str):
            raise _refuse(name, f"{field!r} must be a string")
    actions = reply.get("actions") or {}
    if not isinstance(actions, dict):
        raise _refuse(name, f"'actions' must be an object, got {type(actions).__name__}")
    if len(actions) > MAX_ACTIONS:
        raise _refuse(name, f"{len(actions)} actions (at most {MAX_ACTIONS})")
    action_type = reply.get("action_type")
    if action_type is not None and not isinstance(action_type, str):
        raise _refuse(name, "'action_type' must be a string")
    return {**{f: reply[f][:500] for f in _STRINGS}, "action_type": action_type,
            "inputs": _topics(name, "inputs", reply.get("inputs")),
            "outputs": _topics(name, "outputs", reply.get("outputs")),
            "actions": {m: _action(name, m, raw) for m, raw in actions.items()}}


def allowed(name: str, allow_list: Iterable[str] | None, recipe: Iterable[str] | None,
            always: Iterable[str] = ()) -> bool:
    """Whether Cortex may offer component ``name``'s actions (see the module docstring)."""
    if name in always:
        return True
    chosen = allow_list if allow_list is not None else recipe
    if chosen is None:
        return False
    names = set(chosen)
    return ANY_COMPONENT in names or name in names


#: A closing ``data`` tag as a model may read one: any case, spaces anywhere (``</DATA>``, ``< / data>``).
_CLOSING_DATA = re.compile(r"<\s*/\s*(data)", re.IGNORECASE)


def as_data(source: str, text: str) -> str:
    """``text`` as a block of data from ``source`` (the tool or topic it came from), never instructions.

    A closing tag inside ``text``, written in any case or with spaces, is escaped (``<\\/data``): the block
    ends only where this closes it."""
    body = _CLOSING_DATA.sub(lambda m: f"<\\/{m.group(1)}", text)
    return f'<data source="{source.replace(chr(34), "")[:200]}">\n{body}\n</data>'
