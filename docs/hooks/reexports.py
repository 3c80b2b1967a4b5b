"""A griffe extension (mkdocs.yml, mkdocstrings' ``extensions``): ``from x import A as A`` makes ``A`` public.

The façades (``agents_core.components``, ``.ros``, ``.config``, ...) write each re-exported name
once, as such an import, and write no ``__all__`` (``agents_core.support.lazy`` answers it at run time). Type
checkers read that form as an explicit re-export; griffe, reading the source statically, would
otherwise count every imported name as private and the API reference of a façade would be empty.
"""

from __future__ import annotations

import ast
from typing import Any

import griffe


class ExplicitReexports(griffe.Extension):
    """Marks an alias public when its import names it ``as`` itself (PEP 484's re-export form)."""

    def on_alias_instance(self, *, node: ast.AST | griffe.ObjectNode, alias: griffe.Alias, **kwargs: Any) -> None:
        """Called by griffe for each alias it creates while visiting a module."""
        if not isinstance(node, ast.ImportFrom):
            return
        if any(name.asname == name.name == alias.name for name in node.names):
            alias.public = True
