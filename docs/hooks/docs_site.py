"""MkDocs hooks of the documentation site (mkdocs.yml ``hooks``): included repository files, offline link rules.

- A page whose first line is ``<!-- include: PATH -->`` (PATH relative to the repository root) is
  replaced by that file, so the README stays the one copy of its prose (GitHub's landing page and the
  site's home). Its relative links are rewritten for the page's place in ``docs/``: a link into ``docs/``
  points at that page, a link to another file of the repository points at ``repo_url`` when
  mkdocs.yml sets one and otherwise becomes its text (the site only holds ``docs/``).
- External links are never fetched (CI builds offline); their form is checked instead: ``https://``
  with a dotted host name, or ``http://`` only to a loopback address. MkDocs' own validation
  (``strict`` with ``validation.links``) checks every internal link and anchor.
- Sphinx roles left in docstring text (``:class:`~pkg.Name```) become cross-references to the API
  reference where it documents that name, and plain code otherwise (mkdocstrings parses the
  ``:param:`` fields of Sphinx-style docstrings, not the roles in their prose).
- The ``:param:`` lines of an attrs class (``@define``) document the fields of the ``__init__`` that
  attrs writes at import, and those of a class without an ``__init__`` of its own the arguments its
  base's ``__init__`` passes on through ``**kwargs``: griffe's static analysis sees neither, so its two
  unknown-parameter warnings are dropped for such classes only. A stale ``:param:`` of a function or
  of a class's own ``__init__`` still fails the build.
"""

from __future__ import annotations

import logging
import posixpath
import re
from pathlib import Path
from typing import Any

log = logging.getLogger("mkdocs.hooks.docs_site")

_INCLUDE = re.compile(r"\A<!--\s*include:\s*(\S+)\s*-->")  # the page's first line
#: An inline Markdown link ``[text](target)``; images (``![...]``) are left alone.
_LINK = re.compile(r"(?<!!)\[(?P<text>[^\]\n]+)\]\((?P<target>[^)\s]+)\)")
_FENCE = re.compile(r"^\s*(```|~~~)")
_LOOPBACK = re.compile(r"^http://(127\.0\.0\.1|localhost|\[::1\])(:\d+)?(/|$)")
_HTTPS = re.compile(r"^https://[A-Za-z0-9-]+(\.[A-Za-z0-9-]+)+(:\d+)?(/|$)")


_UNSEEN_PARAM = re.compile(r"^(?:griffe: )?(?P<path>[^:]+\.py):(?P<line>\d+): (No matching parameter for|Parameter) '")
_ATTRS_DECORATOR = re.compile(r"^\s*@(attrs\.|attr\.)?(define|frozen|mutable|attrs|s)\b")


def _is_generated_init_docstring(path: str, line: int) -> bool:
    """True when ``line`` of ``path`` (1-based) is in the docstring of an attrs class or of a class
    without an ``__init__`` of its own."""
    try:
        lines = Path(path).read_text(encoding="utf-8").splitlines()
    except OSError:
        return False
    index = min(line, len(lines)) - 1
    while index >= 0 and not lines[index].lstrip().startswith(("class ", "def ", "async def ")):
        index -= 1
    if index < 0 or not lines[index].lstrip().startswith("class "):
        return False
    if not _defines_init(lines, index):
        return True
    index -= 1
    while index >= 0 and lines[index].lstrip().startswith("@"):
        if _ATTRS_DECORATOR.match(lines[index]):
            return True
        index -= 1
    return False


def _defines_init(lines: list[str], class_index: int) -> bool:
    """Whether the class whose ``class`` line is ``lines[class_index]`` defines ``__init__`` in its body."""
    indent = len(lines[class_index]) - len(lines[class_index].lstrip())
    for text in lines[class_index + 1:]:
        stripped = text.lstrip()
        if stripped and len(text) - len(stripped) <= indent and not stripped.startswith((")", "#")):
            return False  # the class body ended
        if stripped.startswith("def __init__("):
            return True
    return False


class _AttrsInitParameters(logging.Filter):
    """Drops griffe's unknown-parameter warnings on attrs classes (their ``__init__`` is generated)."""

    def filter(self, record: logging.LogRecord) -> bool:
        found = _UNSEEN_PARAM.match(record.getMessage())
        return not (found and _is_generated_init_docstring(found.group("path"), int(found.group("line"))))


def on_startup(command: str, dirty: bool) -> None:
    """Install the attrs filter on mkdocstrings' griffe logger (MkDocs' hook entry point)."""
    griffe_log = logging.getLogger("mkdocs.plugins.griffe")
    if not any(isinstance(f, _AttrsInitParameters) for f in griffe_log.filters):
        griffe_log.addFilter(_AttrsInitParameters())


def _outside_fences(markdown: str, rewrite: Any) -> str:
    """``rewrite(line)`` applied to every line that is not inside a fenced code block."""
    out, fenced = [], False
    for line in markdown.split("\n"):
        if _FENCE.match(line):
            fenced = not fenced
            out.append(line)
        else:
            out.append(line if fenced else rewrite(line))
    return "\n".join(out)


def _rewrite_links(markdown: str, source: str, page: str, repo_url: str | None) -> str:
    """The links of ``source`` (a repository path) made right for the site page ``page`` (a docs/ path)."""
    source_dir, page_dir = posixpath.dirname(source), posixpath.dirname(page)

    def one(match: re.Match[str]) -> str:
        target = match.group("target")
        if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
            return match.group(0)
        path, _, anchor = target.partition("#")
        where = posixpath.normpath(posixpath.join(source_dir, path))
        if where.startswith("docs/"):
            new = posixpath.relpath(where.removeprefix("docs/"), page_dir or ".")
            return f"[{match.group('text')}]({new}{'#' + anchor if anchor else ''})"
        if repo_url:
            return f"[{match.group('text')}]({repo_url.rstrip('/')}/blob/main/{where}{'#' + anchor if anchor else ''})"
        return match.group("text")

    return _outside_fences(markdown, lambda line: _LINK.sub(one, line))


def _check_external_links(markdown: str, page: str) -> None:
    def check(line: str) -> str:
        for match in _LINK.finditer(line):
            target = match.group("target")
            if target.startswith("http") and not (_HTTPS.match(target) or _LOOPBACK.match(target)):
                log.warning("%s: external link %s is neither https:// to a named host nor http:// to loopback",
                            page, target)
        return line

    _outside_fences(markdown, check)


_ROLE = re.compile(r":(?:py:)?(?:class|func|meth|attr|mod|data|exc|obj|const):"
                   r"<code>(?P<tilde>~?)(?P<target>[^<]+)</code>")


def _roles_to_references(html: str) -> str:
    """``:role:<code>~a.b.C</code>`` (a Sphinx role as Markdown renders it) -> an optional autoref showing ``C``."""

    def one(match: re.Match[str]) -> str:
        target = match.group("target").strip().removesuffix("()")
        shown = target.rsplit(".", 1)[-1] if match.group("tilde") else target
        if not re.fullmatch(r"[A-Za-z_][\w.]*", target):
            return f"<code>{match.group('target')}</code>"
        return f'<autoref identifier="{target}" optional><code>{shown}</code></autoref>'

    return _ROLE.sub(one, html)


def on_page_content(html: str, page: Any, config: Any, files: Any) -> str:
    """Turn the Sphinx roles of rendered docstrings into references (MkDocs' hook entry point)."""
    return _roles_to_references(html)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    """Put included files in place, then check the external links' form (MkDocs' hook entry point)."""
    page_path = page.file.src_uri
    found = _INCLUDE.search(markdown)
    if found:
        root = Path(config["config_file_path"]).resolve().parent
        source = found.group(1)
        included = root / source
        if not included.is_file():
            log.warning("%s: includes %s, which does not exist", page_path, source)
            return markdown
        markdown = _rewrite_links(included.read_text(encoding="utf-8"), source, page_path, config.get("repo_url"))
    _check_external_links(markdown, page_path)
    return markdown
