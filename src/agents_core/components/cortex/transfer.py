"""How a Cortex's ``actions`` cross to its own process (``add_pkg(..., multiprocessing=True)``).

Upstream's recipes give Cortex plain functions of the recipe (``Action(method=toggle_led,
description=...)``). Such an Action crosses as its function's ``module:qualname`` (the child
imports the recipe file, so the function runs there, in Cortex's process), its arguments and its
description. A method bound to an object (a component's, say) cannot be rebuilt in another
process and is refused at ``add_pkg``, naming it, as functions are.

Decoding trusts the name no further than the encoder made it: the name must be a plain Python
function defined under exactly that ``module:qualname``, in a module already loaded in this
process (the recipe and what it imports). A crafted spec therefore cannot import a module nobody
loaded (importing runs its code), nor reach a builtin (``builtins:eval``, ``os:system``) or walk an
attribute chain (``agents_recipe:os.system``).
"""

from __future__ import annotations

import inspect
import sys
from typing import Any

from ...actions import Action
from ...errors import ConfigError
from ...transport.process_values import TAG, ValueCodec, decode_value, encode_value, register_value_codec

__all__ = ["ACTION_CODEC"]


def _encode_action(action: Action) -> dict[str, Any]:
    where = f"Action {action.name!r}"
    return {"method": encode_value(action.method, where), "args": encode_value(list(action.args), where),
            "kwargs": encode_value(action.kwargs, where), "description": action.description}


def _action_function(data: Any) -> Any:
    """The function an encoded Action names, checked as the module docstring says (ConfigError if not)."""
    path = data.get("v") if isinstance(data, dict) and data.get(TAG) == "function" else None
    if not isinstance(path, str):
        raise ConfigError(f"an Action's method must be encoded as a function name, got {str(data)[:80]!r}")
    module_name, _, qualname = path.partition(":")
    module = sys.modules.get(module_name)
    if module is None:
        raise ConfigError(f"Action function {path[:200]!r}: its module is not loaded in this process "
                          "(only functions of the recipe and the modules it imports cross)")
    func: Any = module
    for part in qualname.split("."):
        func = getattr(func, part, None)
    # Defined in that very module (its globals are the module's): the recipe runs under its own name.
    if not inspect.isfunction(func) or func.__globals__ is not vars(module) or func.__qualname__ != qualname:
        raise ConfigError(f"Action function {path[:200]!r} is not a function defined under that name")
    return func


def _decode_action(data: dict[str, Any]) -> Action:
    return Action(_action_function(data["method"]), args=tuple(decode_value(data["args"])),
                  kwargs=decode_value(data["kwargs"]), description=data.get("description"))


#: The process value codec of :class:`~agents_core.actions.Action` (registered on import).
ACTION_CODEC = register_value_codec(ValueCodec("action", Action, _encode_action, _decode_action))
