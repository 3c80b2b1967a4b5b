"""The lazy façades: each re-exported name is written once, as an import under ``if TYPE_CHECKING:``.

That block is the façade's table (:func:`agents_core._lazy.lazy_facade` reads it at the first
attribute looked up); ``__all__`` (what type checkers and the API reference read) must list each of
its names and nothing that does not exist (beyond them: what the module defines, or declares for its
own ``__getattr__``, such as ``__version__``).
"""

from __future__ import annotations

import importlib
import subprocess
import sys
from pathlib import Path

import pytest

from agents_core._lazy import facade_imports

SRC = Path(__file__).resolve().parent.parent / "src"
FACADES = sorted(
    ".".join(path.relative_to(SRC).with_suffix("").parts).removesuffix(".__init__")
    for path in (SRC / "agents_core").rglob("*.py")
    if path.name != "_lazy.py" and "lazy_facade(__name__" in path.read_text(encoding="utf-8"))


def test_the_facades_are_found() -> None:
    assert {"agents_core", "agents_core.components", "agents_core.ros", "agents_core.clients"} <= set(FACADES)


@pytest.mark.parametrize("name", FACADES)
def test_all_lists_exactly_the_type_checking_imports_and_what_the_module_defines(name: str) -> None:
    module = importlib.import_module(name)
    spec = module.__spec__
    assert spec is not None and spec.origin is not None
    imported = set(facade_imports(Path(spec.origin).read_text(encoding="utf-8")))
    assert imported, f"{name}: no TYPE_CHECKING imports found"
    listed = set(module.__all__)
    assert imported <= listed, f"{name}: imported for re-export but not in __all__: {sorted(imported - listed)}"
    eager = listed - imported
    missing = sorted(n for n in eager if n not in vars(module) and n not in vars(module).get("__annotations__", {}))
    assert not missing, f"{name}: __all__ names {missing}, neither imported under TYPE_CHECKING nor defined"


def test_the_reader_understands_every_import_form() -> None:
    source = ("x = 1\nif TYPE_CHECKING:\n    from . import base_validators\n    from .a import A, B  # two\n"
              "    from ..b.c import (\n        C,\n        D as D,\n    )\nelse:\n    from .z import Z\n")
    assert facade_imports(source) == {"base_validators": (".", "base_validators"), "A": (".a", "A"),
                                      "B": (".a", "B"), "C": ("..b.c", "C"), "D": ("..b.c", "D")}


def test_a_name_is_resolved_on_first_use_only() -> None:
    code = ("import sys, agents_core.components as c\n"
            "assert 'agents_core.components.llm' not in sys.modules\n"
            "assert c.LLM is sys.modules['agents_core.components.llm'].LLM\n"
            "import agents_core.ros as r\n"
            "assert r.base_validators is sys.modules['agents_core.base_validators']\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
