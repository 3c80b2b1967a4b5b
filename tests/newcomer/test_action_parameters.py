"""Item 4 of issue 38: a ``@component_action`` is described with its parameters (JSON Schema from its signature,
annotations and docstring) wherever actions are shown or offered, and its arguments can be passed by name.

The talker example's documented ``agentsctl call talker set_word '{"word": "hello"}'`` runs against the example
itself on Zenoh (loopback, in its own process) and the talker then says "hello"."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Literal

import pytest

from agents_core import Launcher, Topic
from agents_core.actions import component_action
from agents_core.components import Component

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = REPO / "examples"


class Arm(Component):
    """A component whose action has every kind of parameter."""

    @component_action
    def move(self, joint: str, angle: float, speed: int = 2, mode: Literal["abs", "rel"] = "abs",
             note: str | None = None, flags: list[bool] | None = None) -> str:
        """Move one joint.

        :param joint: the joint's name
        :param angle: where to, in radians
        :param speed: how fast (1-5)
        """
        return f"{joint} {angle} {speed} {mode} {note} {flags}"


def _arm() -> Arm:
    return Arm(inputs=[], outputs=[], trigger=1.0, component_name="arm")


def test_the_schema_has_types_defaults_required_and_descriptions() -> None:
    described = _arm().available_actions()["move"]["function"]
    assert described["description"] == "Move one joint."
    assert described["parameters"] == {
        "type": "object", "required": ["joint", "angle"], "additionalProperties": False,
        "properties": {
            "joint": {"type": "string", "description": "the joint's name"},
            "angle": {"type": "number", "description": "where to, in radians"},
            "speed": {"type": "integer", "default": 2, "description": "how fast (1-5)"},
            "mode": {"enum": ["abs", "rel"], "default": "abs"},
            "note": {"type": ["string", "null"], "default": None},
            "flags": {"type": ["array", "null"], "items": {"type": "boolean"}, "default": None}}}


def test_the_describe_service_the_ui_api_and_an_llm_tool_carry_the_schema() -> None:
    pytest.importorskip("starlette", reason="the ui extra is not installed")
    from starlette.testclient import TestClient  # noqa: PLC0415

    from agents_core.components import LLM  # noqa: PLC0415
    from agents_core.ui import LocalRecipe, UISettings  # noqa: PLC0415
    from agents_core.ui.app import UIState, create_app  # noqa: PLC0415

    arm = _arm()
    launcher = Launcher("memory")
    launcher.add_pkg(components=[arm])
    with launcher:
        described = launcher.transport.request("arm/describe", {}, timeout=5.0)
        assert described["actions"]["move"]["function"]["parameters"]["required"] == ["joint", "angle"]
        # The UI posts the form's answers by name.
        state = UIState(LocalRecipe(launcher.components), launcher.transport, [], [], UISettings())
        with TestClient(create_app(state), base_url="http://127.0.0.1:5001") as client:
            reply = client.post("/api/components/arm/actions/move", json={"kwargs": {"joint": "elbow", "angle": 0.5}})
        assert reply.status_code == 200, reply.text
        assert reply.json()["result"] == "elbow 0.5 2 abs None None"
    from agents_core.clients.ollama import OllamaClient  # noqa: PLC0415
    from agents_core.models import OllamaModel  # noqa: PLC0415

    client = OllamaClient(OllamaModel(name="m", checkpoint="qwen3:0.6b"), port=1)
    llm = LLM(inputs=[Topic("q", "String")], outputs=[Topic("a", "String")], trigger=Topic("q", "String"),
              model_client=client, component_name="talky")
    llm.register_tool(arm.move)  # no hand-written description: the action's own
    tool = llm._tool_descriptions()[0]["function"]
    assert tool["name"] == "move" and tool["parameters"]["properties"]["speed"]["default"] == 2


def test_arguments_by_name_through_execute_method() -> None:
    arm = _arm()
    launcher = Launcher("memory")
    launcher.add_pkg(components=[arm])
    with launcher:
        ask = launcher.transport.request
        by_name = ask("arm/execute_method", {"method": "move", "args": [{"joint": "wrist", "angle": 1}]}, timeout=5)
        positional = ask("arm/execute_method", {"method": "move", "args": ["wrist", 1]}, timeout=5)
        with pytest.raises(Exception, match=r"missing a required argument: 'angle'.*takes \(joint, angle"):
            ask("arm/execute_method", {"method": "move", "args": [{"joint": "wrist"}]}, timeout=5)
    assert by_name["result"] == positional["result"] == "wrist 1 2 abs None None"


def _cli(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "agents_core.cli", *args], cwd=REPO, capture_output=True,
                          text=True, timeout=timeout, check=False)


def _documented_call() -> list[str]:
    """The ``agentsctl call`` line of examples/talker.py's docstring, as words."""
    import shlex  # noqa: PLC0415

    line = next(t.strip() for t in (EXAMPLES / "talker.py").read_text().splitlines()
                if t.strip().startswith("agentsctl call talker"))
    return shlex.split(line)[1:]


@pytest.mark.zenoh
def test_the_talkers_documented_call_sets_the_word(tmp_path: Path) -> None:
    pytest.importorskip("zenoh")
    from agents_core.testing.helpers import free_tcp_port  # noqa: PLC0415

    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    log = (tmp_path / "talker.log").open("wb")
    talker = subprocess.Popen([sys.executable, str(EXAMPLES / "talker.py"), "--transport", "zenoh", "--listen",
                               endpoint, "--seconds", "120"], cwd=EXAMPLES, stdout=log, stderr=subprocess.STDOUT)
    try:
        called: Any = None
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            done = _cli(*_documented_call(), "--transport", "zenoh", "--connect", endpoint, "--json")
            if done.returncode == 0:
                called = json.loads(done.stdout)
                break
            time.sleep(1.0)
        assert called is not None, f"agentsctl call never answered: {done.stderr[-1500:]}"
        assert called["result"] == "now saying hello"
        heard = _cli("topics", "echo", "chatter", "--count", "1", "--json", "--transport", "zenoh",
                     "--connect", endpoint)
        assert heard.returncode == 0, heard.stderr
        assert json.loads(heard.stdout)["value"].startswith("hello ")
        status = _cli("components", "status", "talker", "--transport", "zenoh", "--connect", endpoint)
        assert "word: string" in status.stdout, status.stdout
    finally:
        talker.terminate()
        try:
            talker.wait(timeout=20)
        except subprocess.TimeoutExpired:
            talker.kill()
            talker.wait(timeout=10)
        log.close()


def test_the_ui_button_asks_for_each_parameter_and_runs_the_action() -> None:
    """The button of an action with parameters: one question per parameter, then the action runs with them."""
    pytest.importorskip("starlette", reason="the ui extra is not installed")
    pytest.importorskip("playwright", reason="playwright is not installed")
    if not Path("/usr/bin/chromium").is_file():
        pytest.skip("Debian's Chromium is not at /usr/bin/chromium (apt-get install -y chromium)")
    from playwright.sync_api import sync_playwright  # noqa: PLC0415

    arm = _arm()
    launcher = Launcher("memory")
    launcher.add_pkg(components=[arm])
    launcher.enable_ui(inputs=[], outputs=[], port=0)
    answers = iter(["elbow", "0.25", "", "", "", ""])
    asked: list[str] = []
    with launcher, sync_playwright() as p:
        browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=["--no-sandbox"])
        try:
            page = browser.new_page()

            def answer(dialog: Any) -> None:
                asked.append(dialog.message)
                dialog.accept(next(answers))

            page.on("dialog", answer)
            page.goto(launcher.ui.url)
            page.locator('.component[data-name="arm"] button[data-action="move"]').click()
            page.wait_for_selector('#toast:has-text("elbow 0.25")', timeout=20_000)
            toast = page.locator("#toast").inner_text()
        finally:
            browser.close()
    assert toast.endswith('"elbow 0.25 2 abs None None"'), toast
    assert asked[0] == "move: joint (string) — the joint's name"
    assert asked[2] == "move: speed (integer) (optional) — how fast (1-5)"


def _beep() -> None:
    """Beep once."""


def test_the_cortex_is_offered_the_actions_parameters() -> None:
    from agents_core.actions import Action  # noqa: PLC0415
    from agents_core.clients import GenericHTTPClient  # noqa: PLC0415
    from agents_core.components import Cortex  # noqa: PLC0415
    from agents_core.models import GenericLLM  # noqa: PLC0415
    from agents_core.testing.helpers import free_tcp_port  # noqa: PLC0415

    cortex = Cortex(actions=[Action(_beep)], component_name="cortex",
                    model_client=GenericHTTPClient(GenericLLM(name="planner", checkpoint="planner"),
                                                   port=free_tcp_port()))
    arm = _arm()
    cortex._offer("arm", arm.component_description())  # what the Cortex does with each describe reply
    tool = cortex._tools.get("arm.move")
    assert tool is not None
    assert tool.parameters["required"] == ["joint", "angle"]
    assert tool.parameters["properties"]["angle"] == {"type": "number", "description": "where to, in radians"}
