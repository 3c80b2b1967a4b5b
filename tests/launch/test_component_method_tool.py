"""Another component's action given as a tool crosses to a component process as a ComponentMethod.

``memory.register_tools_on(llm)`` hands the LLM bound ``@component_action`` methods of the memory.
With ``multiprocessing=True`` the LLM's process gets a :class:`ComponentMethod` instead, which calls
the owner's ``execute_method`` service; any other bound method is still refused at ``add_pkg``.
"""

from __future__ import annotations

import json
import os

import pytest

from agents_core.declarations.component_method import ComponentMethod
from agents_core.errors import ComponentError, ConfigError
from agents_core.launch.launcher import Launcher
from agents_core.launch.spec import ComponentSpec, decode_value, encode_value
from agents_core.ros import Topic

from .mp_recipe import Shout


def test_a_bound_component_action_crosses_as_a_reference_by_name() -> None:
    shout = Shout("in_t", "out_t", "shouter", suffix="?")
    crossed = decode_value(json.loads(json.dumps(encode_value(shout.set_suffix, "tool"))))
    assert crossed == ComponentMethod("shouter", "set_suffix")
    assert crossed.__name__ == "set_suffix" and callable(crossed)
    # Called without a transport, it says where it runs instead of doing nothing.
    with pytest.raises(ComponentError, match="another process"):
        crossed(suffix="!")


def test_other_bound_methods_are_still_refused() -> None:
    shout = Shout("in_t", "out_t", "shouter", suffix="?")
    with pytest.raises(ConfigError, match="method bound to a Shout"):
        encode_value(shout.get_logger, "tool")  # a method, not a @component_action


def test_an_llm_with_another_components_tool_is_transferable() -> None:
    pytest.importorskip("jinja2")
    from agents_core.components import LLM  # noqa: PLC0415
    from agents_core.config import LLMConfig  # noqa: PLC0415

    shout = Shout("in_t", "out_t", "shouter", suffix="?")
    question = Topic(name="q", msg_type="String")
    llm = LLM(inputs=[question], outputs=[Topic(name="a", msg_type="String")], trigger=question,
              config=LLMConfig(enable_local_model=True), component_name="asker")
    llm.register_tool(shout.set_suffix, {"name": "set_suffix", "description": "d", "parameters": {
        "type": "object", "properties": {"suffix": {"type": "string"}}, "required": ["suffix"]}})
    spec = ComponentSpec.from_component(llm, "zenoh", {}, os.getpid())
    call = json.loads(json.dumps(spec.to_dict()))["setup_calls"][0]
    assert call["method"] == "register_tool"
    assert decode_value(call["args"][0]) == ComponentMethod("shouter", "set_suffix")


def test_call_runs_the_action_on_its_component_through_the_transport() -> None:
    shout = Shout("in_t", "out_t", "shouter", suffix="?")
    launcher = Launcher(transport="memory")
    launcher.add_pkg(components=[shout])
    with launcher:
        result = ComponentMethod("shouter", "set_suffix").call(launcher.transport, {"suffix": "!"})
        assert result == "!" and shout.suffix == "!"
        with pytest.raises(Exception, match="no action 'nope'"):
            ComponentMethod("shouter", "nope").call(launcher.transport, {})

