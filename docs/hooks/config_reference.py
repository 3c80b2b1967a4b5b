"""MkDocs hook: the configuration reference, a table of fields with their real defaults, read from the source.

A page line ``<!-- config-reference: PATH [PATH ...] -->`` (paths relative to the repository root) is
replaced by one section per ``@define`` config class of those files: its summary, its base, and a
table of its own fields (name, type, default, description from the class's ``:param`` lines).

Why not mkdocstrings alone: attrs writes each config's ``__init__`` at import, so static analysis
(griffe) sees no signature and shows every field as "required". This reads the class bodies with
:mod:`ast` instead (nothing is imported: the docs build needs neither the project nor its
dependencies), taking ``field(default=...)``, ``field(factory=...)`` and plain assignments.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path
from typing import Any

__all__ = ["config_sections", "on_page_markdown"]

_MARKER = re.compile(r"^<!--\s*config-reference:\s*(?P<paths>[^>]+?)\s*-->$", re.MULTILINE)
_ROLE = re.compile(r":(?:class|meth|func|attr|mod|data|obj|exc):`~?(?P<target>[^`]+)`")
_PARAM = re.compile(r"^:param\s+(?P<name>\w+):\s*(?P<text>.*)$")
_FACTORIES = {"dict": "{}", "list": "[]", "set": "set()", "tuple": "()"}


def _plain(text: str) -> str:
    """Docstring text for a Markdown table cell: Sphinx roles as code, ``double`` quotes as single, pipes escaped."""
    text = _ROLE.sub(lambda m: f"`{m.group('target').rsplit('.', 1)[-1]}`", text)
    return text.replace("``", "`").replace("|", "\\|")


def _params(doc: str) -> dict[str, str]:
    found: dict[str, str] = {}
    current: str | None = None
    for raw in doc.splitlines():
        line = raw.strip()
        match = _PARAM.match(line)
        if match:
            current = match.group("name")
            found[current] = match.group("text").strip()
        elif current is not None and line and raw.startswith((" ", "\t")):
            found[current] += " " + line
        else:
            current = None
    return found


def _summary(doc: str) -> str:
    return " ".join(doc.strip().split("\n\n")[0].split())


def _is_config_class(node: ast.ClassDef) -> bool:
    def name(dec: ast.expr) -> str:
        target = dec.func if isinstance(dec, ast.Call) else dec
        return ast.unparse(target)

    return any(name(d).split(".")[-1] in ("define", "frozen") for d in node.decorator_list) or any(
        ast.unparse(b).endswith(("BaseAttrs", "Config")) for b in node.bases)


def _default(value: ast.expr | None) -> str | None:
    """The default as source text; None when the field has none (required)."""
    if value is None:
        return None
    if isinstance(value, ast.Call) and ast.unparse(value.func).split(".")[-1] in ("field", "ib", "attrib"):
        for kw in value.keywords:
            if kw.arg == "default":
                return _factory_text(kw.value)
            if kw.arg == "factory":
                return _FACTORIES.get(ast.unparse(kw.value), f"{ast.unparse(kw.value)}()")
        return None
    return _factory_text(value)


def _factory_text(value: ast.expr) -> str:
    if isinstance(value, ast.Call) and ast.unparse(value.func).split(".")[-1] == "Factory" and value.args:
        return _FACTORIES.get(ast.unparse(value.args[0]), f"{ast.unparse(value.args[0])}()")
    return ast.unparse(value)


def _fields(node: ast.ClassDef) -> list[tuple[str, str, str | None]]:
    out = []
    for stmt in node.body:
        if isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name):
            name = stmt.target.id
            annotation = ast.unparse(stmt.annotation)
            if name.startswith("_") or annotation.startswith(("ClassVar", "typing.ClassVar")):
                continue
            out.append((name, annotation, _default(stmt.value)))
    return out


def config_sections(root: Path, paths: list[str]) -> str:
    """The Markdown of the config classes defined in ``paths`` (relative to ``root``), in source order."""
    parts: list[str] = []
    for path in paths:
        tree = ast.parse((root / path).read_text(encoding="utf-8"))
        for node in tree.body:
            if not (isinstance(node, ast.ClassDef) and _is_config_class(node)) or node.name.startswith("_"):
                continue
            fields = _fields(node)
            doc = ast.get_docstring(node) or ""
            described = _params(doc)
            bases = ", ".join(f"[{b}](#{b.lower()})" if b.endswith("Config") else f"`{b}`"
                              for b in (ast.unparse(x).split(".")[-1] for x in node.bases))
            parts.append(f"### {node.name}\n")
            if doc:
                parts.append(_plain(_summary(doc)) + "\n")
            if bases:
                parts.append(f"Bases: {bases} (their fields apply too).\n")
            if not fields:
                parts.append("No fields of its own.\n")
                continue
            rows = ["| field | type | default | description |", "|---|---|---|---|"]
            for name, annotation, default in fields:
                shown = "required" if default is None else f"`{default}`"
                rows.append(f"| `{name}` | {_plain(annotation)} | {shown.replace('|', chr(92) + '|')} | "
                            f"{_plain(described.get(name, ''))} |")
            parts.append("\n".join(rows) + "\n")
    return "\n".join(parts)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    """Replace each config-reference marker of a page (MkDocs' hook entry point)."""
    root = Path(config["config_file_path"]).resolve().parent

    def one(match: re.Match[str]) -> str:
        return config_sections(root, match.group("paths").split())

    return _MARKER.sub(one, markdown)
