"""``agentsctl recipe show`` on every file of ``examples/``, checked against the recipe the file builds.

For each example the CLI prints the recipe as JSON in its own process; a probe
(``tests/launch/recipe_probe.py``) captures the same file's :class:`~agents_core.launch.recipe.Recipe`
in another and prints both its data and what its live component and event objects say. The CLI's
JSON must be that data, and agree with the live objects (names, classes, topics, triggers).
Nothing starts: the file runs until its launcher would.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents_core import Component, Launcher, Topic
from agents_core.actions import Action
from agents_core.clients.ollama import OllamaClient
from agents_core.components.llm import LLM
from agents_core.errors import ConfigError
from agents_core.events import Event
from agents_core.launch.recipe import Recipe, capture_recipe
from agents_core.models import OllamaModel

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = sorted(p.name for p in (REPO / "examples").glob("*.py"))
#: Files of examples/ that build no launcher (shared helpers).
NOT_RECIPES = {"example_cli.py"}


def _args(name: str, tmp_path: Path) -> list[str]:
    if name == "two_machines.py":
        return ["operator", "--connect", "tcp/127.0.0.1:7447"]
    if name == "vision_tracking.py":
        pytest.importorskip("PIL", reason="the example imports Pillow (the local extra)")
        from PIL import Image  # noqa: PLC0415

        model, images = tmp_path / "detector.onnx", tmp_path / "photos"
        model.write_bytes(b"not read: nothing is configured")
        images.mkdir()
        Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(images / "black.png")
        return ["--model", str(model), "--images", str(images)]
    return []


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, *args], cwd=REPO, capture_output=True, text=True, timeout=120, check=False)


def test_every_example_is_covered() -> None:
    assert "talker.py" in EXAMPLES and len(EXAMPLES) >= 5


@pytest.mark.parametrize("name", EXAMPLES)
def test_recipe_show_prints_the_recipe_of_each_example(name: str, tmp_path: Path) -> None:
    args = _args(name, tmp_path)
    shown = _run("-m", "agents_core.cli", "recipe", "show", f"examples/{name}", *args)
    if name in NOT_RECIPES:
        assert shown.returncode == 1 and "never starts a launcher" in shown.stderr, shown.stderr
        return
    assert shown.returncode == 0, shown.stderr[-3000:]
    printed = json.loads(shown.stdout)  # stdout holds the JSON document alone
    probe = _run("tests/launch/recipe_probe.py", f"examples/{name}", *args)
    assert probe.returncode == 0, probe.stderr[-3000:]
    captured = json.loads(probe.stdout)
    assert printed == captured["recipe"]
    live = captured["live"]
    assert live["equal_when_captured_twice"] is True
    assert printed["format"] == "agents_core.recipe/1"
    assert [c["name"] for c in printed["components"]] == [c["name"] for c in live["components"]]
    for data, obj in zip(printed["components"], live["components"], strict=True):
        assert data["class"] == obj["class"]
        assert [[t["name"], t["type"]] for t in data["inputs"]] == obj["inputs"]
        assert [[t["name"], t["type"]] for t in data["outputs"]] == obj["outputs"]
        kind, what = obj["trigger"]
        if kind == "topic":
            assert data["trigger"]["v"]["name"] == what
        elif kind == "event":
            assert data["trigger"]["name"] == what
        elif kind == "topics":
            assert [t["v"]["name"] for t in data["trigger"]] == what
        else:
            assert data["trigger"] == what
    assert [[e["event"]["name"], [a["name"] for a in e["actions"]]] for e in printed["events_actions"]] == \
        live["events"]
    assert printed["settings"]["multiprocessing"] is live["multiprocessing"]
    assert sorted(printed["attachments"]) == live["attachments"]


def test_the_talker_example_in_detail() -> None:
    shown = _run("-m", "agents_core.cli", "recipe", "show", "examples/talker.py", "--compact")
    assert shown.returncode == 0 and shown.stdout.count("\n") == 1, shown.stderr
    recipe = json.loads(shown.stdout)
    talker, listener = recipe["components"]
    assert (talker["name"], talker["class"], talker["trigger"], talker["run_type"]) == (
        "talker", "__main__:Talker", 5.0, "Timed")
    assert talker["outputs"] == [{"name": "chatter", "type": "String"}]
    assert listener["trigger"]["v"]["name"] == "chatter" and listener["run_type"] == "Event"
    assert listener["kwargs"]["heard"] == {"__agents_value__": "local only", "v": "threading:Event"}
    assert recipe["settings"]["transport"] is None and recipe["settings"]["multiprocessing"] is False


class Echo(Component):
    """Publishes what it hears."""

    def _execution_step(self, **kwargs: Any) -> None:
        return None


def _recipe(tmp_path: Path, key: str = "sk-secret") -> tuple[Launcher, LLM]:
    q = Topic("q", "String")
    llm = LLM(inputs=[q], outputs=[Topic("a", "String")], trigger=q, component_name="brain",
              model_client=OllamaClient(OllamaModel(name="m", checkpoint="llama3.2:1b"), api_key=key))
    launcher = Launcher(transport="memory", quiet=True)
    go = Event("go", Topic("go_t", "Bool").msg.data == True)  # noqa: E712  # builds a condition
    launcher.add_pkg(components=[llm, Echo(inputs=[q], trigger=q, component_name="echo")],
                     events_actions={go: Action(llm.deactivate)})
    launcher.on_fail("restart", max_retries=2)
    launcher.fallback_rate = 2.0
    return launcher, llm


def test_a_recipe_is_data_that_compares_and_says_what_was_done_after_construction(tmp_path: Path) -> None:
    launcher, llm = _recipe(tmp_path)
    same, _ = _recipe(tmp_path)
    assert launcher.recipe == same.recipe
    llm.set_component_prompt("all: {{ q }}")  # a setup call, recorded
    llm.fallback_rate = 0.5  # an attribute assigned after construction, recorded
    assert launcher.recipe != same.recipe
    data = launcher.recipe.to_dict()
    brain = data["components"][0]
    assert brain["setup_calls"] == [{"method": "set_component_prompt", "args": ["all: {{ q }}"], "kwargs": {}}]
    assert brain["attributes"] == {"fallback_rate": 0.5}
    assert data["events_actions"] == [{"event": {"name": "go", "topics": ["go_t"]}, "actions": [
        {"name": "deactivate", "owner": "brain", "args": [], "kwargs": {}, "description": None}]}]
    assert data["settings"]["on_fail"] == {"action_name": "restart", "max_retries": 2}
    assert data["settings"]["fallback_rate"] == 2.0
    text = launcher.recipe.to_json()
    assert "sk-secret" not in text and "<redacted>" in text  # the client's API key is not shown
    assert json.loads(text) == data


def test_capture_refuses_a_file_that_never_launches(tmp_path: Path) -> None:
    script = tmp_path / "nothing.py"
    script.write_text("x = 1\n")
    with pytest.raises(ConfigError, match="never starts a launcher"):
        capture_recipe(script)
    recipe = tmp_path / "one.py"
    recipe.write_text("from agents_core import Launcher, Topic\n"
                      "from tests.launch.test_recipe_show import Echo\n"
                      "t = Topic('t', 'String')\n"
                      "launcher = Launcher(transport='memory')\n"
                      "launcher.add_pkg(components=[Echo(inputs=[t], trigger=t, component_name='echo')])\n"
                      "launcher.bringup()\n")
    captured = capture_recipe(recipe)
    assert isinstance(captured, Recipe) and [c.component_name for c in captured.components] == ["echo"]
    assert not captured.components[0].runtime.is_bound  # captured, never started
