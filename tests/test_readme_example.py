"""The README's testing example, run as written (examples that no test runs will rot)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

README = Path(__file__).resolve().parent.parent / "README.md"


def _python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def test_readme_component_and_test_example_run() -> None:
    blocks = _python_blocks()
    component = next(b for b in blocks if "class Shout" in b)
    test = next(b for b in blocks if "def test_shout" in b)
    namespace: dict[str, Any] = {}
    exec(compile(component + "\n" + test, str(README), "exec"), namespace)
    namespace["test_shout"]()
