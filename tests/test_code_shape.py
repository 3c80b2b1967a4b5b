"""The shape of src/, checked: no import circle, no oversized file, no one writing another class's privates.

These are the structural promises of docs/architecture.md:

- the only import circle among the modules of ``src/`` is ``topics`` <-> ``conditions`` (the
  condition language's entry point: ``topic.msg.data > 3`` builds a condition);
- the modules sit in the layers of :data:`LAYERS` (lowest first) and at most
  :data:`MAX_BACK_ARROWS` imports run from a lower layer up to a higher one; nothing in
  ``components/`` imports the launch wing;
- no file in ``src/`` is over :data:`MAX_LINES` lines;
- no module assigns an underscore attribute of an object other than ``self`` / ``cls`` (a class's
  private state is written by that class only).

Imports are read with :mod:`ast`: those at module level count, ``if TYPE_CHECKING:`` ones too (a
type-level dependency is a dependency), except in a package's ``__init__`` and in a module that is a
lazy façade (``lazy_facade(__name__ ...)``, such as ``config``): those name what they re-export for
type checkers only, and import it at first use; imports inside functions do not count. Importing
``a.b.c`` also runs ``a/__init__`` and ``a/b/__init__``.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "src"
PACKAGES = ("agents_core", "agents_zenoh", "agents_ros2")
MAX_LINES = 600
#: The file that defines ``Launcher``: a thin façade over a recipe and a run (issue 35).
LAUNCHER_MAX_LINES = 350
#: Import circles that are part of the design (sorted module names).
ALLOWED_CYCLES = {("agents_core.conditions", "agents_core.topics")}
#: The layers of agents_core, lowest first: name -> the package-root modules / folders in it. A module
#: may import its own layer and those below; the adapters (agents_zenoh, agents_ros2) sit with the
#: transport's users, at :data:`ADAPTER_LAYER`. The package root (``agents_core/__init__``, a lazy
#: façade importing only ``support.lazy`` at run time) is in the base.
LAYERS: tuple[tuple[str, frozenset[str]], ...] = (
    ("base", frozenset({"", "support", "errors", "base_validators", "utils", "status", "telemetry"})),
    ("vocabulary", frozenset({"types", "supported_types", "messages", "config", "topics",
                              "conditions", "events", "actions", "callbacks", "declarations", "models",
                              "vectordbs", "guardrails"})),
    ("transport", frozenset({"transport"})),
    ("runtime", frozenset({"runtime"})),
    ("clients", frozenset({"clients", "engines"})),
    ("components", frozenset({"components", "sim"})),
    ("wings", frozenset({"launch", "recording", "foxglove", "ui", "episodes", "evals", "mcp"})),
    ("entry points", frozenset({"cli", "testing", "demo", "demo_eval", "ros", "example_servers"})),
)
ADAPTER_LAYER = "runtime"
#: At most this many imports run back up the layers (each one listed in docs/architecture.md).
MAX_BACK_ARROWS = 2

#: Places that assign another object's underscore attribute on purpose: (module, "target._attr"): why.
ALLOWED_PRIVATE_WRITES = {
    # __new__ records the constructor's arguments on the instance it just made (its own object).
    ("agents_core.components.component_base", "instance._init_arguments"): "Component.__new__",
}


def _modules() -> dict[str, Path]:
    found: dict[str, Path] = {}
    for package in PACKAGES:
        for path in sorted((SRC / package).rglob("*.py")):
            parts = list(path.relative_to(SRC).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            found[".".join(parts)] = path
    return found


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _module_imports(tree: ast.Module, type_checking: bool) -> Iterator[ast.Import | ast.ImportFrom]:
    """Import statements at module level (try/if bodies too; ``if TYPE_CHECKING:`` ones if ``type_checking``)."""
    stack: list[ast.stmt] = list(tree.body)
    while stack:
        node = stack.pop()
        if isinstance(node, ast.Import | ast.ImportFrom):
            yield node
        elif isinstance(node, ast.If):
            if type_checking or not _is_type_checking(node.test):
                stack.extend(node.body)
            stack.extend(node.orelse)
        elif isinstance(node, ast.Try):
            stack.extend([*node.body, *node.orelse, *node.finalbody])
            for handler in node.handlers:
                stack.extend(handler.body)


def _with_parents(module: str, known: dict[str, Path]) -> set[str]:
    parts = module.split(".")
    return {".".join(parts[:i]) for i in range(1, len(parts) + 1) if ".".join(parts[:i]) in known}


def _import_graph() -> dict[str, set[str]]:
    known = _modules()
    graph: dict[str, set[str]] = {name: set() for name in known}
    for name, path in known.items():
        is_package = path.name == "__init__.py"
        text = path.read_text(encoding="utf-8")
        facade = is_package or "lazy_facade(__name__" in text
        for node in _module_imports(ast.parse(text), type_checking=not facade):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            else:
                if node.level:
                    base = name.split(".") if is_package else name.split(".")[:-1]
                    base = base[: len(base) - (node.level - 1)]
                    prefix = ".".join(base + ([node.module] if node.module else []))
                else:
                    prefix = node.module or ""
                targets = [prefix]
                # `from package import submodule` imports the submodule too.
                targets += [f"{prefix}.{alias.name}" for alias in node.names if f"{prefix}.{alias.name}" in known]
            for target in targets:
                for dep in _with_parents(target, known):
                    if dep != name and not name.startswith(dep + "."):
                        graph[name].add(dep)
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[tuple[str, ...]]:
    """Strongly connected components of more than one module (Tarjan, iterative-safe for this size)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    found: list[tuple[str, ...]] = []
    counter = [0]

    def visit(node: str) -> None:
        index[node] = low[node] = counter[0]
        counter[0] += 1
        stack.append(node)
        on_stack.add(node)
        for dep in sorted(graph[node]):
            if dep not in index:
                visit(dep)
                low[node] = min(low[node], low[dep])
            elif dep in on_stack:
                low[node] = min(low[node], index[dep])
        if low[node] == index[node]:
            component = []
            while True:
                top = stack.pop()
                on_stack.discard(top)
                component.append(top)
                if top == node:
                    break
            if len(component) > 1:
                found.append(tuple(sorted(component)))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def test_no_import_circle_but_topics_and_conditions() -> None:
    unexpected = [cycle for cycle in _cycles(_import_graph()) if cycle not in ALLOWED_CYCLES]
    assert not unexpected, f"import circles in src/: {unexpected}"


def test_the_cycle_finder_finds_a_circle() -> None:
    # The checker itself must be able to fail.
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [("a", "b", "c")]


def _layer(module: str) -> int:
    names = [name for name, _ in LAYERS]
    if not module.startswith("agents_core"):
        return names.index(ADAPTER_LAYER)
    first = module[len("agents_core"):].lstrip(".").split(".")[0]
    for index, (_, members) in enumerate(LAYERS):
        if first in members:
            return index
    raise AssertionError(f"module {module} is in no layer of tests/test_code_shape.py LAYERS: place it there")


def _back_arrows(graph: dict[str, set[str]]) -> list[str]:
    return sorted(f"{module} -> {dep}" for module, deps in graph.items() for dep in deps
                  if _layer(dep) > _layer(module))


def test_at_most_two_imports_run_back_up_the_layers() -> None:
    arrows = _back_arrows(_import_graph())
    assert len(arrows) <= MAX_BACK_ARROWS, "imports running up the layers:\n" + "\n".join(arrows)


def test_the_back_arrow_counter_counts_one() -> None:
    graph = {"agents_core.topics": {"agents_core.launch.spec"}, "agents_core.launch.spec": {"agents_core.topics"}}
    assert _back_arrows(graph) == ["agents_core.topics -> agents_core.launch.spec"]


def test_no_component_imports_the_launch_wing() -> None:
    found = [f"{module} -> {dep}" for module, deps in _import_graph().items() if module.startswith(
        "agents_core.components") for dep in deps if dep.startswith("agents_core.launch")]
    assert not found, f"components importing the launcher: {found}"


def test_no_file_in_src_is_over_the_limit() -> None:
    sizes = {str(path.relative_to(SRC)): len(path.read_text(encoding="utf-8").splitlines())
             for path in _modules().values()}
    too_long = {name: lines for name, lines in sizes.items() if lines > MAX_LINES}
    assert not too_long, f"files over {MAX_LINES} lines: {too_long}"


def _private_writes(name: str, tree: ast.Module) -> Iterator[tuple[str, int]]:
    for node in ast.walk(tree):
        targets: list[ast.expr] = []
        if isinstance(node, ast.Assign):
            targets = node.targets
        elif isinstance(node, ast.AugAssign | ast.AnnAssign):
            targets = [node.target]
        flat: list[ast.expr] = []
        for target in targets:
            flat.extend(target.elts if isinstance(target, ast.Tuple | ast.List) else [target])
        for target in flat:
            if (isinstance(target, ast.Attribute) and target.attr.startswith("_")
                    and not target.attr.startswith("__")):
                owner = ast.unparse(target.value)
                if owner not in ("self", "cls") and (name, f"{owner}.{target.attr}") not in ALLOWED_PRIVATE_WRITES:
                    yield f"{owner}.{target.attr}", node.lineno
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "setattr"
                and len(node.args) >= 2 and isinstance(node.args[1], ast.Constant)
                and str(node.args[1].value).startswith("_") and not str(node.args[1].value).startswith("__")):
            owner = ast.unparse(node.args[0])
            if owner not in ("self", "cls"):
                yield f"setattr({owner}, {node.args[1].value!r})", node.lineno


def test_no_module_writes_another_objects_private_attributes() -> None:
    found = [f"{name}:{line}: {what}" for name, path in _modules().items()
             for what, line in _private_writes(name, ast.parse(path.read_text(encoding="utf-8")))]
    assert not found, "private attributes written from outside their class:\n" + "\n".join(found)


def test_the_private_write_finder_finds_one() -> None:
    tree = ast.parse("def f(c):\n    c._worker = None\n    self._ok = 1\n")
    assert [what for what, _ in _private_writes("m", tree)] == ["c._worker"]


def test_the_launcher_stays_a_thin_facade() -> None:
    lines = (SRC / "agents_core" / "launch" / "launcher.py").read_text(encoding="utf-8").count("\n")
    assert lines <= LAUNCHER_MAX_LINES, f"launch/launcher.py has {lines} lines (at most {LAUNCHER_MAX_LINES})"
