"""Lazy re-exports for the façades (PEP 562 module ``__getattr__`` and ``__dir__``), each name written once.

A robot process that only relays topics should not pay for the model stack (httpx, jinja2, the
clients, the model components) because a package re-exports those names. A façade writes each name
it re-exports once, as an explicit re-export (``X as X``) under ``if TYPE_CHECKING:``, and installs
the pair :func:`lazy_facade` builds::

    if TYPE_CHECKING:
        from .launch.launcher import Launcher as Launcher
        from .topics import QoSConfig as QoSConfig
        from .topics import Topic as Topic
    else:
        __getattr__, __dir__ = lazy_facade(__name__)

Those imports are the whole table: type checkers read them (``X as X`` is what marks a re-export
under mypy's ``--strict``), and :func:`lazy_facade` reads the same lines from the module's source at
the first attribute looked up, never at import. ``__all__`` (what ``from façade import *`` reads) is
answered from them too: the re-exports, in source order, then the names the module defines itself
(``own``). A name the module imports eagerly at the top level as ``X as X`` is a re-export as well,
and is listed in ``__all__``.

The first access of a name imports its module and caches the value in the façade, so later
accesses are plain attribute reads. Keeping ``__getattr__`` in the ``else:`` branch keeps it out of
the type checkers' sight, so a typo'd name stays an error for them.

The source is read with ``re`` (loaded at start-up anyway), not ``ast``, whose import and parse
cost a recipe's import several milliseconds; ``tests/test_facades.py`` checks the reading against
``ast`` for every façade.
"""

from __future__ import annotations

import importlib
import importlib.util
import re
import sys
from collections.abc import Callable, Iterable, Mapping
from importlib.machinery import ModuleSpec
from types import ModuleType
from typing import Any, NamedTuple

__all__ = ["FacadeTable", "facade_table", "keep_moved_modules", "lazy_exports", "lazy_facade"]


def lazy_exports(
    module_name: str,
    exports: Mapping[str, Iterable[str]],
    *,
    modules: Mapping[str, str] | None = None,
    import_all_for: Iterable[str] = (),
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``(__getattr__, __dir__)`` pair of ``module_name``, resolving the names of ``exports`` on first use.

    :param module_name: the re-exporting module's ``__name__``.
    :param exports: module path (relative to the module's package, e.g. ``".topics"``) -> the names
        it re-exports from there. A name may appear only once.
    :param modules: re-exported names that are modules themselves, name -> module path.
    :param import_all_for: names whose value is only complete once every module of ``exports`` has
        been imported (a registry filled by class definitions): accessing one imports them all first.
    :returns: the two functions, to assign to ``__getattr__`` and ``__dir__`` in that module.

    On a package, an attribute that is none of these but names a submodule imports the submodule,
    as an eager ``__init__`` that imported it used to make ``package.submodule`` work.
    """
    where: dict[str, str] = {}
    for module, names in exports.items():
        for name in names:
            if name in where:
                raise ValueError(f"{module_name}: {name!r} is exported from both {where[name]} and {module}")
            where[name] = module
    module_names = dict(modules or {})
    for name in module_names:
        if name in where:
            raise ValueError(f"{module_name}: {name!r} is exported both as a module and from {where[name]}")
    everything = frozenset(import_all_for)
    unknown = sorted(everything - set(where))
    if unknown:
        raise ValueError(f"{module_name}: import_all_for names {unknown}, which are not exported")
    this = sys.modules[module_name]
    package = this.__package__ or module_name
    is_package = hasattr(this, "__path__")

    def _import(path: str, name: str) -> Any:
        try:
            return importlib.import_module(path, package)
        except AttributeError as exc:
            # An AttributeError escaping __getattr__ would read as "no such name" (hasattr() says False)
            # and hide the real failure inside the imported module.
            raise ImportError(f"importing {path} (package {package}) for {module_name}.{name} failed: {exc}") from exc

    def __getattr__(name: str) -> Any:
        if name in where:
            if name in everything:
                for path in exports:
                    _import(path, name)
            value = getattr(_import(where[name], name), name)
        elif name in module_names:
            value = _import(module_names[name], name)
        elif is_package and not name.startswith("__") and importlib.util.find_spec(f"{module_name}.{name}"):
            return importlib.import_module(f"{module_name}.{name}")  # the import binds it on the package
        else:
            raise AttributeError(f"module {module_name!r} has no attribute {name!r}")
        setattr(this, name, value)  # cached: the next access does not come here
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(this)) | set(where) | set(module_names))

    return __getattr__, __dir__


class FacadeTable(NamedTuple):
    """What a façade's source re-exports (:func:`facade_table`)."""

    #: Re-exported under ``if TYPE_CHECKING:`` (resolved on first use): name -> (module path, name there).
    lazy: dict[str, tuple[str, str]]
    #: Re-exported by a top-level ``from PATH import X as X`` (bound at import), in source order.
    eager: list[str]
    #: Imports under ``if TYPE_CHECKING:`` that are not written ``X as X``: "PATH: NAME" each.
    not_explicit: list[str]


_FROM_IMPORT = re.compile(r"^from\s+(\.*[\w.]*)\s+import\s+(.+)$")


def _statements(lines: Iterable[str]) -> Iterable[tuple[bool, str]]:
    """``(indented, statement)`` for each statement; a parenthesised import is joined into one line."""
    statement, indented = "", False
    for line in lines:
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        if statement:
            statement = f"{statement} {text}"
        else:
            statement, indented = text, line[:1] in (" ", "\t")
        if statement.startswith("from ") and (statement.count("(") > statement.count(")") or statement.endswith("\\")):
            statement = statement.removesuffix("\\")
            continue  # the import goes on
        yield indented, statement
        statement = ""


def _imported(statement: str) -> tuple[str, list[tuple[str, str, bool]]] | None:
    """``from P import A, B as B`` -> ``(P, [(A, A, False), (B, B, True)])``: (name there, name here, re-export)."""
    match = _FROM_IMPORT.match(statement)
    if match is None:
        return None
    found = []
    for item in (part.strip() for part in match.group(2).replace("(", "").replace(")", "").split(",")):
        if item:
            original, as_, alias = (word.strip() for word in item.partition(" as "))
            found.append((original, alias or original, bool(as_) and alias == original))
    return match.group(1), found


def facade_table(source: str) -> FacadeTable:
    """Read a façade's re-exports from its source text (see the module docstring for the forms).

    Lines before ``from __future__ import annotations`` (the docstring) are not read; an import
    renamed on the way (``A as B``) is not a re-export.
    """
    lines = source.splitlines()
    start = next((i + 1 for i, line in enumerate(lines) if line.startswith("from __future__ import")), 0)
    table = FacadeTable({}, [], [])
    inside = False
    for indented, statement in _statements(lines[start:]):
        if not indented:
            inside = statement == "if TYPE_CHECKING:"
        if inside and not indented:
            continue
        found = _imported(statement) if inside or not indented else None
        if found is None:
            if inside:
                table.not_explicit.append(statement)
            continue
        path, names = found
        for original, name, explicit in names:
            if inside and explicit:
                table.lazy[name] = (path, original)
            elif inside:
                table.not_explicit.append(f"{path}: {original}")
            elif explicit:
                table.eager.append(name)
    return table


def lazy_facade(module_name: str, *, own: Iterable[str] = (),
                import_all_for: Iterable[str] = ()) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """:func:`lazy_exports` whose table is the module's own ``if TYPE_CHECKING:`` re-exports (each name written once).

    :param module_name: the façade's ``__name__``.
    :param own: the public names the module defines itself (added to ``__all__`` after the re-exports).
    :param import_all_for: as for :func:`lazy_exports`.

    The module's source is read at the first attribute looked up, never at import. A name imported
    as a submodule (``from . import base_validators as base_validators``) resolves to that module.
    ``__all__`` is answered (and cached on the module) at its first access, ``_EXPORTS`` and
    ``_MODULE_EXPORTS`` give the derived table as data.
    """
    this = sys.modules[module_name]
    defined = tuple(own)
    pair: tuple[Callable[[str], Any], Callable[[], list[str]]] | None = None
    #: The derived table, as :func:`lazy_exports` takes it (also answered as ``_EXPORTS`` / ``_MODULE_EXPORTS``).
    exports: dict[str, tuple[str, ...]] = {}
    modules: dict[str, str] = {}
    names: list[str] = []

    def _pair() -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
        nonlocal pair
        if pair is None:
            spec = this.__spec__
            loader = getattr(spec, "loader", None)
            source = loader.get_source(module_name) if loader is not None and hasattr(loader, "get_source") else None
            table = facade_table(source or "")
            if table.not_explicit:
                raise ValueError(f"{module_name}: write each import under TYPE_CHECKING as `X as X` (a façade's "
                                 f"re-export), not {table.not_explicit}")
            package = this.__package__ or module_name
            for name, (path, _original) in table.lazy.items():
                base = importlib.util.resolve_name(path, package) if path.startswith(".") else path
                if path.endswith(".") and importlib.util.find_spec(f"{base}.{name}") is not None:
                    modules[name] = f"{path}{name}"
                else:
                    exports[path] = (*exports.get(path, ()), name)
            listed = [*table.eager, *table.lazy, *defined]
            doubled = sorted({n for n in listed if listed.count(n) > 1})
            if doubled:
                raise ValueError(f"{module_name}: {doubled} are exported more than once")
            names[:] = listed
            pair = lazy_exports(module_name, exports, modules=modules, import_all_for=import_all_for)
        return pair

    def __getattr__(name: str) -> Any:
        if name == "__all__":
            _pair()
            listed = list(names)
            vars(this)["__all__"] = listed  # cached: asked again, it is a plain attribute
            return listed
        if name.startswith("__"):  # ``__path__``, ``__file__``, ...: never a re-export (and asked while building)
            raise AttributeError(f"module {module_name!r} has no attribute {name!r}")
        if name in ("_EXPORTS", "_MODULE_EXPORTS"):  # the table itself, as data
            _pair()
            return dict(exports) if name == "_EXPORTS" else dict(modules)
        return _pair()[0](name)

    def __dir__() -> list[str]:
        return sorted({*_pair()[1](), *names})

    return __getattr__, __dir__


class _MovedModule:
    """The loader of a module's old path: the module it moved to, imported (once) and bound under both names."""

    def __init__(self, new_name: str) -> None:
        self.new_name = new_name
        self._spec: ModuleSpec | None = None

    def create_module(self, spec: ModuleSpec) -> ModuleType:
        module = importlib.import_module(self.new_name)
        self._spec = module.__spec__  # the import system writes the old path's spec over it: put back below
        return module

    def exec_module(self, module: ModuleType) -> None:
        module.__spec__ = self._spec  # already executed under its own name: only its own spec is restored


class _MovedModules:
    """A meta path finder answering the old paths of moved modules (see :func:`keep_moved_modules`)."""

    def __init__(self) -> None:
        self.moves: dict[str, str] = {}

    def find_spec(self, fullname: str, path: object = None, target: object = None) -> ModuleSpec | None:
        new_name = self.moves.get(fullname)
        if new_name is None:
            return None
        loader: Any = _MovedModule(new_name)  # PEP 451 (create_module, exec_module); typeshed asks load_module
        return importlib.util.spec_from_loader(fullname, loader)


_MOVED = _MovedModules()


def keep_moved_modules(moves: Mapping[str, str]) -> None:
    """Keep the old import path of each moved module working: old dotted name -> new dotted name.

    ``import old`` (and ``from old import x``, ``from package import old``) then gives the module at
    its new place, the same object, imported once: classes keep their new ``__module__``. Type
    checkers do not see the old paths; code of this project imports the new ones.
    """
    _MOVED.moves.update(moves)
    if _MOVED not in sys.meta_path:
        sys.meta_path.append(_MOVED)
