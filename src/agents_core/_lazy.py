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

The first access of a name imports its module and caches the value in the package, so later
accesses are plain attribute reads. Type checkers and IDEs read the ``TYPE_CHECKING`` imports;
keeping ``__getattr__`` out of their sight also keeps a typo'd name an error for them.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from collections.abc import Callable, Iterable, Mapping
from typing import Any

__all__ = ["lazy_exports"]


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
