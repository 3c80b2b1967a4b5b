"""Importing a recipe file in a component process without launching the recipe again.

A component process imports the recipe file by path, for the component classes defined in it.
Recipes often build a launcher and call ``launcher.bringup()`` at the top level (no
``if __name__ == "__main__":`` guard); in a component process, ``Launcher.start()`` then raises
:class:`RecipeImportStop`, which :func:`import_recipe` catches: the recipe stops there, and
everything it defined before (its classes) is available. (This lives in a module of its own, not
in ``child``: that one runs as ``__main__``, under another name than the launcher would look up.)
"""

from __future__ import annotations

import importlib.util
import sys
from types import ModuleType

__all__ = ["RecipeImportStop", "import_recipe", "importing_recipe"]

_importing = False


class RecipeImportStop(BaseException):  # a control-flow signal, like SystemExit
    """Raised by ``Launcher.start()`` while a component process imports the recipe file."""


def importing_recipe() -> bool:
    """True while :func:`import_recipe` runs a recipe file in this process."""
    return _importing


def import_recipe(path: str, module_name: str) -> ModuleType:
    """Import the recipe file ``path`` as ``module_name``, stopping where it would launch."""
    global _importing  # noqa: PLW0603  # one import at a time, in a component process
    spec = importlib.util.spec_from_file_location(module_name, path)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot import the recipe {path!r}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module
    _importing = True
    try:
        spec.loader.exec_module(module)
    except RecipeImportStop:
        pass
    finally:
        _importing = False
    return module
