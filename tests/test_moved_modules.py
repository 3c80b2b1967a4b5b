"""Modules moved from the package root into folders keep their old import paths (the same module object)."""

from __future__ import annotations

import ast
import subprocess
import sys
import textwrap
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "src"


def test_every_old_path_imports_the_moved_module_once() -> None:
    code = textwrap.dedent("""
        import importlib, sys
        import agents_core
        from agents_core.support.lazy import _MOVED
        moves = dict(_MOVED.moves)
        assert len(moves) == 13, moves
        for old, new in moves.items():
            module = importlib.import_module(old)
            assert module is sys.modules[new] is importlib.import_module(new), old
            assert module.__name__ == new and module.__spec__.name == new, (old, module.__spec__)
        from agents_core.install_hint import install_hint
        from agents_core.setup_calls import setup_method
        from agents_core import bounded_json
        assert install_hint.__module__ == "agents_core.support.install_hint"
        assert setup_method.__module__ == "agents_core.declarations.setup_calls"
        assert bounded_json is sys.modules["agents_core.support.bounded_json"]
        print(sorted(moves))
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    for old in ast.literal_eval(done.stdout.strip()):
        path = SRC / (old.replace(".", "/") + ".py")
        assert not path.exists(), f"{path} is back at the root: it would shadow the moved module"


def test_an_unknown_root_module_is_still_an_import_error() -> None:
    code = "import agents_core\ntry:\n    import agents_core.no_such_module\nexcept ImportError:\n    print('ok')\n"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
    assert done.stdout.strip() == "ok", done.stderr
