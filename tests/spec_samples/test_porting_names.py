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


def _module_table(page: Path) -> dict[str, str]:
    """The "one change" table of docs/porting.md: upstream module -> the first module named as its home."""
    text = page.read_text(encoding="utf-8")
    section = text[text.index("## The one change"):]
    section = section[:section.index("\n## ", 1)]
    homes: dict[str, str] = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        upstream, here = (_CODE.search(cells[0]), _CODE.search(cells[1])) if len(cells) >= 2 else (None, None)
        if line.startswith("|") and upstream and here:
            homes.setdefault(upstream.group(1), here.group(1))
    return homes


def _sugarcoat_names(spec: str) -> set[str]:
    """Every name the spec says comes from Sugarcoat (``ros_sugar``): imported, or marked so in the text."""
    names = {n.strip() for _, group in re.findall(r"from (ros_sugar[\w.]*) import ([\w, ]+)", spec)
             for n in group.split(",")}
    names |= set(re.findall(r"^\s*(?:\W+\s*)?(\w+) \(ros_sugar\)", spec, re.MULTILINE))  # the hierarchy drawings
    names |= set(re.findall(r"`(\w+)` \(Sugarcoat\)", spec))
    names |= set(re.findall(r"`(\w+)` is provided by \[Sugarcoat\]", spec))
    return names


def test_every_ros_sugar_module_the_spec_imports_has_a_documented_home() -> None:
    spec = spec_text()
    imported = set(re.findall(r"from (ros_sugar[\w.]*) import ([\w, ]+)", spec))
    assert imported, "the spec imports ros_sugar names"
    table = _module_table(PORTING)
    from .spec_blocks import RENAMES  # noqa: PLC0415 - the rewrite the samples apply must be the documented one

    rewrites = {pattern.pattern.replace("\\b", "").replace("\\.", "."): home for pattern, home in RENAMES}
    for module, names in imported:
        assert module in table, f"docs/porting.md's module table has no row for {module}"
        assert rewrites.get(module) == table[module], (module, rewrites.get(module), table[module])
        for name in (n.strip() for n in names.split(",")):
            assert _resolve(f"{table[module]}.{name}") is not None, f"{module}.{name}"


def test_every_name_the_spec_gives_to_sugarcoat_has_a_row_and_a_home() -> None:
    names = _sugarcoat_names(spec_text())
    assert {"BaseComponent", "BaseComponentConfig", "SupportedType", "add_additional_datatypes",
            "GenericCallback"} <= names, names
    rows = dict(ROWS)
    missing = sorted(names - set(rows))
    assert not missing, f"spec names from Sugarcoat without a row in docs/porting.md's table: {missing}"
    for name in names:
        assert _resolve(rows[name]) is not None, name


def test_the_decision_on_a_ros_sugar_import_path_is_written_with_its_reason() -> None:
    text = PORTING.read_text(encoding="utf-8")
    decision = next((p for p in text.split("\n\n") if "`ros_sugar`" in p and "opt-in" in p), None)
    assert decision, "docs/porting.md does not say whether an opt-in ros_sugar import path ships"
    assert "shadow" in decision, "the decision has no reason (a module of Sugarcoat's name would shadow it)"
    # No module of Sugarcoat's name ships here (docs/porting.md says why).
    found = importlib.util.find_spec("ros_sugar")
    assert found is None or not str(found.origin).startswith(str(REPO / "src"))
    assert not (REPO / "src" / "ros_sugar").exists()
