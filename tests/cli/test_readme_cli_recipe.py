"""The README's ``agentsctl`` section shows the recipe its commands drive: kept equal to tests/cli/cli_recipe.py."""

from __future__ import annotations

import inspect
import re
from pathlib import Path
from typing import Any

from agents_core import Launcher, Topic
from tests.cli import cli_recipe

README = Path(__file__).resolve().parents[2] / "README.md"


def _talker_block() -> str:
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), flags=re.S)
    return next(b for b in blocks if "class Talker(Component)" in b)


def test_readme_talker_is_the_cli_recipes_talker() -> None:
    assert inspect.getsource(cli_recipe.Talker) in _talker_block(), \
        "README.md's agentsctl recipe drifted from tests/cli/cli_recipe.py: copy the Talker class over"


def test_readme_names_where_component_action_comes_from() -> None:
    block = _talker_block()
    assert "from agents_core.actions import component_action" in block
    assert "tests/cli/cli_recipe.py" in README.read_text(encoding="utf-8")


def test_readme_talker_block_runs_and_its_action_answers() -> None:
    namespace: dict[str, Any] = {"__name__": "readme_block"}
    exec(compile(_talker_block(), str(README), "exec"), namespace)  # the __main__ part does not run
    talker = namespace["Talker"](inputs=[], outputs=[Topic("chatter", "String"), Topic("camera", "Image")],
                                 trigger=20.0, component_name="talker")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[talker])
    with launcher:
        reply = launcher.transport.request("talker/execute_method", {"method": "set_word", "args": ["hello"]},
                                           timeout=5.0)
    assert reply == {"result": "now saying hello"}
