"""The ``execute_method`` request: a wrong key is answered with the keys it expects (not "no action None")."""

from __future__ import annotations

from typing import Any

import pytest

from agents_core import Launcher, Topic
from agents_core.actions import component_action
from agents_core.components import Component
from agents_core.errors import RemoteError
from agents_core.runtime.services import EXECUTE_METHOD_KEYS


class Greeter(Component):
    """One action, ``greet(who)``."""

    def _execution_step(self, **kwargs: Any) -> None:
        return None

    @component_action
    def greet(self, who: str) -> str:
        """Say hello."""
        return f"hello {who}"


@pytest.fixture
def greeter_transport() -> Any:
    cmd = Topic("cmd", "String")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[Greeter(inputs=[cmd], trigger=cmd, component_name="greeter")])
    with launcher:
        yield launcher.transport


def test_the_documented_payload_runs(greeter_transport: Any) -> None:
    reply = greeter_transport.request("greeter/execute_method",
                                      {"method": "greet", "args": ["ada"], "kwargs": {}, "timeout": 5.0})
    assert reply == {"result": "hello ada"}
    assert EXECUTE_METHOD_KEYS == ("method", "args", "kwargs", "timeout", "caller", "call_id", "approval_timeout")


@pytest.mark.parametrize("request_doc, what", [
    ({"name": "greet", "args": ["ada"]}, "unknown key(s) ['name']"),
    ({"action": "greet"}, "unknown key(s) ['action']"),
    ({"args": ["ada"]}, "no 'method' key"),
    ({"method": "greet", "arguments": ["ada"]}, "unknown key(s) ['arguments']"),
])
def test_a_wrong_key_names_the_expected_keys(greeter_transport: Any, request_doc: dict[str, Any], what: str) -> None:
    with pytest.raises(RemoteError) as caught:
        greeter_transport.request("greeter/execute_method", request_doc)
    text = str(caught.value)
    assert what in text
    assert "expected keys 'method', 'args', 'kwargs', 'timeout'" in text
    assert "no action None" not in text


def test_an_unknown_method_still_lists_the_actions(greeter_transport: Any) -> None:
    with pytest.raises(RemoteError, match=r"has no action 'gret'; available: \['greet'"):
        greeter_transport.request("greeter/execute_method", {"method": "gret"})
