"""docs/porting.md's table of remaining differences from the developer docs names real things.

Each row of the table between ``<!-- spec-names:start -->`` and ``<!-- spec-names:end -->`` gives a
name the spec uses (it must appear in the spec's text) and its home here (a dotted path that must
import: a module, then attributes).
"""

from __future__ import annotations

import importlib
import importlib.util
import re
from pathlib import Path
from typing import Any

import pytest

from .spec_blocks import REPO, spec_text

PORTING = REPO / "docs" / "porting.md"
_CODE = re.compile(r"`([^`]+)`")


def _rows(page: Path) -> list[tuple[str, str]]:
    text = page.read_text(encoding="utf-8")
    start, end = text.index("<!-- spec-names:start -->"), text.index("<!-- spec-names:end -->")
    rows = []
    for line in text[start:end].splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 3 or cells[0] in ("Spec", "---"):
            continue
        spec_name, home = _CODE.search(cells[0]), _CODE.search(cells[1])
        assert spec_name and home, f"docs/porting.md row without a `name` in its first two columns: {line}"
        rows.append((spec_name.group(1), home.group(1)))
    return rows


def _resolve(dotted: str) -> Any:
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            found: Any = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attr in parts[cut:]:
            found = getattr(found, attr)
        return found
    raise ImportError(dotted)


ROWS = _rows(PORTING)


def test_the_table_has_the_rows_issue_37_asked_for() -> None:
    names = {spec for spec, _ in ROWS}
    assert {"_call_inference", "Default Model", "LocalTTS", "device_local_model", "supports_tool_calls",
            "automatika_embodied_agents", "colcon build", "GenericCallback", "SupportedType",
            "add_additional_datatypes"} <= names


@pytest.mark.parametrize(("spec_name", "home"), ROWS, ids=[spec for spec, _ in ROWS])
def test_every_spec_name_in_the_porting_table_exists_in_the_spec_and_here(spec_name: str, home: str) -> None:
    assert spec_name in spec_text(), f"{spec_name!r} is not a name of the spec"
    assert _resolve(home) is not None


def test_every_ros_sugar_module_the_spec_imports_has_a_home() -> None:
    spec = spec_text()
    imported = set(re.findall(r"from (ros_sugar[\w.]*) import ([\w, ]+)", spec))
    assert imported, "the spec imports ros_sugar names"
    homes = {"ros_sugar.supported_types": "agents_core.supported_types",
             "ros_sugar.io.callbacks": "agents_core.callbacks"}
    for module, names in imported:
        for name in (n.strip() for n in names.split(",")):
            assert _resolve(f"{homes[module]}.{name}") is not None, f"{module}.{name}"
    # No module of Sugarcoat's name ships here (docs/porting.md says why).
    found = importlib.util.find_spec("ros_sugar")
    assert found is None or not str(found.origin).startswith(str(REPO / "src"))
    assert not (REPO / "src" / "ros_sugar").exists()
