"""How a Cortex's ``actions`` cross to its own process (``add_pkg(..., multiprocessing=True)``).

Upstream's recipes give Cortex plain functions of the recipe (``Action(method=toggle_led,
description=...)``). Such an Action crosses as its function's ``module:qualname`` (the child
imports the recipe file, so the function runs there, in Cortex's process), its arguments and its
description. A method bound to an object (a component's, say) cannot be rebuilt in another
process and is refused at ``add_pkg``, naming it, as functions are.
"""

from __future__ import annotations

from typing import Any

from ...actions import Action
from ...launch.spec import ValueCodec, decode_value, encode_value, register_value_codec

__all__ = ["ACTION_CODEC"]


def _encode_action(action: Action) -> dict[str, Any]:
    where = f"Action {action.name!r}"
    return {"method": encode_value(action.method, where), "args": encode_value(list(action.args), where),
            "kwargs": encode_value(action.kwargs, where), "description": action.description}


def _decode_action(data: dict[str, Any]) -> Action:
    return Action(decode_value(data["method"]), args=tuple(decode_value(data["args"])),
                  kwargs=decode_value(data["kwargs"]), description=data.get("description"))


#: The process value codec of :class:`~agents_core.actions.Action` (registered on import).
ACTION_CODEC = register_value_codec(ValueCodec("action", Action, _encode_action, _decode_action))
