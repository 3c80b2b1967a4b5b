"""Lazy re-exports for the package ``__init__`` modules (PEP 562 module ``__getattr__`` and ``__dir__``).

A robot process that only relays topics should not pay for the model stack (httpx, jinja2, the
clients, the model components) because a package re-exports those names. Each re-exporting module
declares a table, module -> names, and installs the pair this module builds::

    _EXPORTS = {".topics": ("Topic", "QoSConfig"), ".launch.launcher": ("Launcher",)}
    if TYPE_CHECKING:
        from .launch.launcher import Launcher
        from .topics import QoSConfig, Topic
    else:
        __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

Or, with each name written once in the table above the ``__all__`` that type checkers and the
API reference read, let the ``TYPE_CHECKING`` imports *be* the table (:func:`lazy_facade`)::

    if TYPE_CHECKING:
        from .launch.launcher import Launcher
        from .topics import QoSConfig, Topic
    else:
        __getattr__, __dir__ = lazy_facade(__name__)

    __all__ = ["Launcher", "QoSConfig", "Topic"]

The first access of a name imports its module and caches the value in the package, so later
accesses are plain attribute reads. Type checkers and IDEs read the ``TYPE_CHECKING`` imports;
keeping ``__getattr__`` out of their sight also keeps a typo'd name an error for them.
"""

from __future__ import annotations

import importlib
import importlib.util
import re
import sys
from collections.abc import Callable, Iterable, Mapping
from typing import Any

__all__ = ["facade_imports", "lazy_exports", "lazy_facade"]


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


_FROM_IMPORT = re.compile(r"^from\s+(\.*[\w.]*)\s+import\s+(.+)$")


def facade_imports(source: str) -> dict[str, tuple[str, str]]:
    """The names a façade imports under its module-level ``if TYPE_CHECKING:``: name -> (module path, name there).

    Read from the text (``re``, loaded at start-up anyway; not ``ast``, which costs a recipe's
    import tens of milliseconds): ``from PATH import A, B as C`` lines, parenthesised ones too.
    """
    found: dict[str, tuple[str, str]] = {}
    lines = source.splitlines()
    try:
        start = next(i for i, line in enumerate(lines) if line.rstrip() == "if TYPE_CHECKING:")
    except StopIteration:
        return found
    statement = ""
    for line in lines[start + 1:]:
        if line.strip() and not line.startswith((" ", "\t")):
            break  # the block ended (``else:`` or the next statement)
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        statement = f"{statement} {text}".strip() if statement else text
        if statement.count("(") > statement.count(")"):
            continue  # a parenthesised import goes on
        match = _FROM_IMPORT.match(statement)
        statement = ""
        if match is None:
            continue
        module, names = match.group(1), match.group(2).replace("(", "").replace(")", "")
        for item in (part.strip() for part in names.split(",")):
            if item:
                original, _, alias = item.partition(" as ")
                found[(alias or original).strip()] = (module, original.strip())
    return found


def lazy_facade(module_name: str, *, import_all_for: Iterable[str] = ()) -> tuple[Callable[[str], Any],
                                                                                   Callable[[], list[str]]]:
    """:func:`lazy_exports` whose table is the module's own ``if TYPE_CHECKING:`` imports (each name written once).

    The module's source is read at the first attribute looked up, never at import. A name imported
    as a submodule (``from . import base_validators``) resolves to that module.
    """
    this = sys.modules[module_name]
    pair: tuple[Callable[[str], Any], Callable[[], list[str]]] | None = None
    #: The derived table, as :func:`lazy_exports` takes it (also answered as ``_EXPORTS`` / ``_MODULE_EXPORTS``).
    exports: dict[str, tuple[str, ...]] = {}
    modules: dict[str, str] = {}

    def _pair() -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
        nonlocal pair
        if pair is None:
            spec = this.__spec__
            loader = getattr(spec, "loader", None)
            source = loader.get_source(module_name) if loader is not None and hasattr(loader, "get_source") else None
            table = facade_imports(source or "")
            package = this.__package__ or module_name
            for name, (path, original) in table.items():
                if original != name:
                    raise ValueError(f"{module_name}: {original} is re-exported as {name}; a façade keeps the name")
                base = importlib.util.resolve_name(path, package) if path.startswith(".") else path
                if path.endswith(".") and importlib.util.find_spec(f"{base}.{name}") is not None:
                    modules[name] = f"{path}{name}"
                else:
                    exports[path] = (*exports.get(path, ()), name)
            pair = lazy_exports(module_name, exports, modules=modules, import_all_for=import_all_for)
        return pair

    def __getattr__(name: str) -> Any:
        if name.startswith("__"):  # ``__path__``, ``__file__``, ...: never a re-export (and asked while building)
            raise AttributeError(f"module {module_name!r} has no attribute {name!r}")
        if name in ("_EXPORTS", "_MODULE_EXPORTS"):  # the table itself, as data
            _pair()
            return dict(exports) if name == "_EXPORTS" else dict(modules)
        return _pair()[0](name)

    def __dir__() -> list[str]:
        return _pair()[1]()

    return __getattr__, __dir__

