"""Attacks on how a Cortex ``Action`` crosses to its own process (:mod:`agents_core.components.cortex.transfer`).

The spec names the Action's function as ``module:qualname``. A crafted name must not make the
component process import a module nobody loaded, reach a builtin, or walk an attribute chain to
another module's function: only a plain function defined under exactly that name, in a module
already loaded, is rebuilt.
"""

from __future__ import annotations

import os
import sys
from typing import Any

import pytest

from agents_core.components.cortex.transfer import ACTION_CODEC
from agents_core.errors import ConfigError
from agents_core.launch.spec import TAG, decode_value, encode_value
from agents_core.ros import Action


def toggle_led(on: bool = True) -> str:
    """A recipe-style action function."""
    return f"led {'on' if on else 'off'}"


def _action(method: Any) -> dict[str, Any]:
    return {TAG: ACTION_CODEC.name, "v": {"method": method, "args": {TAG: "tuple", "v": []}, "kwargs": {},
                                          "description": "x"}}


def _function(path: str) -> dict[str, Any]:
    return {TAG: "function", "v": path}


def test_a_module_function_still_crosses() -> None:
    back = decode_value(encode_value(Action(toggle_led, kwargs={"on": False}, description="LED")))
    assert back.method is toggle_led and back.kwargs == {"on": False}
    assert back.method(**back.kwargs) == "led off"


@pytest.mark.parametrize("path", [
    "os:system", "builtins:eval", "builtins:exec", "posix:system",  # builtins, not recipe functions
    f"{__name__}:os.system",  # an attribute chain from a loaded module to another module's function
    f"{__name__}:sys.modules.get",
    "subprocess:Popen",  # a class, not a function
    f"{__name__}:toggle_led.__globals__",  # not a function at all
])
def test_a_crafted_name_is_refused(path: str) -> None:
    with pytest.raises(ConfigError):
        decode_value(_action(_function(path)))


def test_a_module_nobody_loaded_is_not_imported() -> None:
    name = "agents_core_security_probe_never_imported"
    assert name not in sys.modules
    with pytest.raises(ConfigError, match="not loaded"):
        decode_value(_action(_function(f"{name}:run")))
    assert name not in sys.modules
    # a real module this process has not loaded (importing it would run its top level)
    assert "this" not in sys.modules  # the Zen of Python prints on import
    with pytest.raises(ConfigError, match="not loaded"):
        decode_value(_action(_function("this:s")))
    assert "this" not in sys.modules


@pytest.mark.parametrize("method", [None, 42, "os:system", ["os", "system"], {TAG: "path", "v": "/bin/sh"},
                                    {TAG: "component method", "v": ["x", "y"]}, _function("x" * 100_000)])
def test_a_method_that_is_not_a_function_name_is_refused(method: Any) -> None:
    with pytest.raises(ConfigError) as refused:
        decode_value(_action(method))
    assert len(str(refused.value)) < 500  # a huge name is not echoed back whole


def test_the_functions_refused_are_real_callables() -> None:
    # the attack would work without the check: these names do resolve to callables
    assert callable(os.system) and callable(eval)
