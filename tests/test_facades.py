"""The lazy façades: each re-exported name is written once, as ``from PATH import X as X``.

Under ``if TYPE_CHECKING:`` such an import is a lazy re-export (mypy reads it, and
:func:`agents_core.support.lazy.lazy_facade` reads the same line at the first attribute looked up); at the
top level it is an eager one. ``__all__`` is not written: the façade answers it from those imports
and from the names it defines itself (``own=``).
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from agents_core.support.lazy import facade_table

SRC = Path(__file__).resolve().parent.parent / "src"
FACADES = sorted(
    ".".join(path.relative_to(SRC).with_suffix("").parts).removesuffix(".__init__")
    for package in ("agents_core", "agents_ros2", "agents_zenoh") for path in (SRC / package).rglob("*.py")
    if path != SRC / "agents_core/support/lazy.py" and "lazy_facade(__name__" in path.read_text(encoding="utf-8"))

#: Package ``__init__``s that were written imports + ``__all__`` (each name twice) and are façades now:
#: one of them going back to an ``__all__`` list drops it from FACADES and fails the test below.
PACKAGE_FACADES = {
    "agents_ros2.conversions", "agents_zenoh", "agents_zenoh.rmw", "agents_zenoh.codecs", "agents_core.types",
    "agents_core.ui", "agents_core.telemetry", "agents_core.foxglove", "agents_core.sim", "agents_core.recording",
    "agents_core.cli", "agents_core.transport", "agents_core.testing", "agents_core.mcp"}


def _source(name: str) -> str:
    spec = importlib.util.find_spec(name)
    assert spec is not None and spec.origin is not None
    return Path(spec.origin).read_text(encoding="utf-8")


def _ast_reexports(tree: ast.Module) -> tuple[dict[str, tuple[str, str]], list[str], list[str]]:
    """What ``ast`` reads as the façade's re-exports: (lazy, eager, imports under TYPE_CHECKING not ``X as X``)."""
    lazy: dict[str, tuple[str, str]] = {}
    eager: list[str] = []
    loose: list[str] = []
    for node in tree.body:
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            for stmt in node.body:
                if not isinstance(stmt, ast.ImportFrom):
                    loose.append(ast.unparse(stmt))
                    continue
                path = "." * stmt.level + (stmt.module or "")
                for alias in stmt.names:
                    if alias.asname == alias.name:
                        lazy[alias.name] = (path, alias.name)
                    else:
                        loose.append(f"{path}: {alias.name}")
        elif isinstance(node, ast.ImportFrom) and node.module != "__future__":
            eager.extend(alias.name for alias in node.names if alias.asname == alias.name)
    return lazy, eager, loose


def test_the_facades_are_found() -> None:
    assert {"agents_core", "agents_core.components", "agents_core.ros", "agents_core.clients",
            "agents_core.config", "agents_core.episodes"} <= set(FACADES)
    missing = sorted(PACKAGE_FACADES - set(FACADES))
    assert not missing, f"no longer façades (an __all__ list back?): {missing}"


def test_no_package_init_writes_all() -> None:
    """No package ``__init__`` of the three packages writes ``__all__``: each is a façade (or exports nothing)."""
    written = []
    for package in ("agents_core", "agents_ros2", "agents_zenoh"):
        for path in (SRC / package).rglob("__init__.py"):
            tree = ast.parse(path.read_text(encoding="utf-8"))
            targets = [t for node in tree.body if isinstance(node, ast.Assign) for t in node.targets]
            targets += [node.target for node in tree.body if isinstance(node, ast.AnnAssign)]
            if any(isinstance(t, ast.Name) and t.id == "__all__" for t in targets):
                written.append(str(path.relative_to(SRC)))
    assert not written, f"package __init__s that write __all__ (write the façade form instead): {sorted(written)}"


@pytest.mark.parametrize("name", FACADES)
def test_the_reader_reads_what_ast_reads(name: str) -> None:
    source = _source(name)
    lazy, eager, loose = _ast_reexports(ast.parse(source))
    assert not loose, f"{name}: imports under TYPE_CHECKING not written `X as X`: {loose}"
    table = facade_table(source)
    assert table.lazy == lazy
    assert table.eager == eager
    assert not table.not_explicit


@pytest.mark.parametrize("name", FACADES)
def test_each_name_is_written_once(name: str) -> None:
    tree = ast.parse(_source(name))
    lazy, eager, _ = _ast_reexports(tree)
    bound = [alias.name for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and node.module != "__future__"
             for alias in node.names if alias.asname == alias.name]
    doubled = sorted({n for n in bound if bound.count(n) > 1})
    assert not doubled, f"{name}: re-exported twice: {doubled}"
    # Names given to import_all_for (a property of a name, not a second list of them) are allowed.
    marked = {id(node) for node in ast.walk(tree) if isinstance(node, ast.Assign)
              and any(isinstance(t, ast.Name) and f"import_all_for={t.id}" in ast.unparse(tree) for t in node.targets)
              for node in ast.walk(node)}
    exported = {*lazy, *eager}
    strings = sorted(node.value for node in ast.walk(tree) if id(node) not in marked
                     and isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in exported)
    assert not strings, f"{name}: re-exported names written again as strings (an __all__?): {strings}"
    assigned = [t.id for node in tree.body if isinstance(node, ast.Assign) for t in node.targets
                if isinstance(t, ast.Name)] + [node.target.id for node in tree.body if isinstance(node, ast.AnnAssign)
                                               and isinstance(node.target, ast.Name)]
    assert "__all__" not in assigned, f"{name}: writes __all__ (the façade answers it from its imports)"


@pytest.mark.parametrize("name", FACADES)
def test_every_name_resolves_and_star_import_and_dir_agree(name: str) -> None:
    module = importlib.import_module(name)
    tree = ast.parse(_source(name))
    lazy, eager, _ = _ast_reexports(tree)
    names = list(module.__all__)
    assert len(names) == len(set(names))
    assert set(lazy) | set(eager) <= set(names)
    own = set(names) - set(lazy) - set(eager)
    defined = {node.name for node in tree.body if isinstance(node, ast.FunctionDef | ast.ClassDef)} | {
        node.target.id for node in tree.body if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)
    } | {t.id for node in tree.body if isinstance(node, ast.Assign) for t in node.targets if isinstance(t, ast.Name)}
    assert own <= defined, f"{name}: own= names {sorted(own - defined)} the module does not define"
    for export in names:
        assert getattr(module, export) is not None, f"{name}.{export}"
    namespace: dict[str, object] = {}
    exec(f"from {name} import *", namespace)
    assert set(namespace) - {"__builtins__"} == set(names)
    assert set(names) <= set(dir(module))


def test_the_reader_understands_every_import_form() -> None:
    source = textwrap.dedent("""
        \"\"\"Docstring: from .q import Q as Q is not read here.\"\"\"
        from __future__ import annotations
        from .e import E as E, F  # F is not re-exported
        from .g import (
            G as G,
        )
        if TYPE_CHECKING:
            from . import base_validators as base_validators
            from .a import A as A, B as B  # two
            from ..b.c import (
                C as C,
                D as D,
            )
            from .x import Renamed as Other
            from .y import Plain
        else:
            from .z import Z as Z
        def f():
            from .w import W as W
    """)
    table = facade_table(source)
    assert table.lazy == {"base_validators": (".", "base_validators"), "A": (".a", "A"), "B": (".a", "B"),
                          "C": ("..b.c", "C"), "D": ("..b.c", "D")}
    assert table.eager == ["E", "G"]
    assert table.not_explicit == [".x: Renamed", ".y: Plain"]


def _facade_package(tmp_path: Path, body: str) -> str:
    """A package ``façade_pkg`` in tmp_path with a module ``mod`` (class M) and the given façade ``__init__``."""
    package = tmp_path / "facade_pkg"
    package.mkdir()
    (package / "mod.py").write_text("class M:\n    pass\n\n\nclass N:\n    pass\n", encoding="utf-8")
    header = ("from __future__ import annotations\nfrom typing import TYPE_CHECKING\n"
              "from agents_core.support.lazy import lazy_facade\n")
    (package / "__init__.py").write_text(header + textwrap.dedent(body), encoding="utf-8")
    return str(tmp_path)


def _run(path: str, code: str) -> subprocess.CompletedProcess[str]:
    env_path = f"{path}:{SRC}"
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False,
                          env={"PYTHONPATH": env_path, "PATH": "/usr/bin:/bin"})


def test_a_name_written_twice_is_refused(tmp_path: Path) -> None:
    path = _facade_package(tmp_path, """
        from .mod import M as M
        if TYPE_CHECKING:
            from .mod import M as M
        else:
            __getattr__, __dir__ = lazy_facade(__name__)
    """)
    done = _run(path, "import facade_pkg\nprint(facade_pkg.__all__)")
    assert done.returncode != 0 and "['M'] are exported more than once" in done.stderr, done.stderr


def test_an_import_that_is_not_a_reexport_is_refused(tmp_path: Path) -> None:
    path = _facade_package(tmp_path, """
        if TYPE_CHECKING:
            from .mod import M as M
            from .mod import N
        else:
            __getattr__, __dir__ = lazy_facade(__name__)
    """)
    done = _run(path, "import facade_pkg\nfacade_pkg.M")
    assert done.returncode != 0 and "`X as X`" in done.stderr and ".mod: N" in done.stderr, done.stderr


def test_a_name_that_does_not_resolve_is_an_import_error(tmp_path: Path) -> None:
    path = _facade_package(tmp_path, """
        if TYPE_CHECKING:
            from .mod import Missing as Missing
        else:
            __getattr__, __dir__ = lazy_facade(__name__)
    """)
    done = _run(path, "import facade_pkg\nassert facade_pkg.__all__ == ['Missing']\nfacade_pkg.Missing")
    assert done.returncode != 0 and "Missing" in done.stderr, done.stderr


def test_a_name_is_resolved_on_first_use_only() -> None:
    code = ("import sys, agents_core.config as cfg\n"
            "assert 'LLMConfig' in cfg.__all__ and 'agents_core.components.llm_config' not in sys.modules\n"
            "import agents_core.components as c\n"
            "assert 'agents_core.components.llm' not in sys.modules\n"
            "assert c.LLM is sys.modules['agents_core.components.llm'].LLM\n"
            "import agents_core.ros as r\n"
            "assert r.base_validators is sys.modules['agents_core.base_validators']\n"
            "assert cfg.LLMConfig is sys.modules['agents_core.components.llm_config'].LLMConfig\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr


@pytest.mark.parametrize(("facade", "name", "blocked", "hint"), [
    ("agents_core.ui", "UIServer", "starlette", "the web UI needs the ui extra"),
    ("agents_core.foxglove", "FoxgloveBridge", "foxglove", "the Foxglove bridge needs the foxglove extra"),
    ("agents_zenoh", "ZenohTransport", "zenoh", None),
])
def test_an_optional_extras_name_loads_on_first_use_with_the_install_line(
        facade: str, name: str, blocked: str, hint: str | None) -> None:
    """The façade's import loads not the extra; asking for the name without it names the install line."""
    lazy = (f"import sys, {facade} as f\n"
            f"assert {blocked!r} not in sys.modules, sorted(m for m in sys.modules if m.startswith({blocked!r}))\n"
            f"assert {name!r} in f.__all__ and {name!r} not in vars(f)\n")
    done = subprocess.run([sys.executable, "-c", lazy], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    if hint is None:
        return
    missing = f"import sys\nsys.modules[{blocked!r}] = None\nimport {facade} as f\nf.{name}\n"
    done = subprocess.run([sys.executable, "-c", missing], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode != 0 and f"ImportError: {hint}" in done.stderr and "pip install" in done.stderr, done.stderr
    # Any other name still answers AttributeError, not the install line.
    other = (f"import {facade} as f\ntry:\n    f.NoSuchName\nexcept AttributeError:\n    pass\n"
             "else:\n    raise SystemExit(1)\n")
    done = subprocess.run([sys.executable, "-c", other], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
