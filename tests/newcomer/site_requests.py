"""What a built documentation site would fetch from elsewhere when opened: external URLs in the tags and
styles a browser loads by itself (not links, which load only when followed), and what the Material theme's
script fetches for a page: mermaid.js from unpkg.com for a diagram, the repository's facts from
api.github.com when ``repo_url`` puts a source button in the header."""

from __future__ import annotations

import re
from html.parser import HTMLParser
from pathlib import Path

__all__ = ["external_requests"]

_LOCAL = re.compile(r"^(?:https?://(?:127\.0\.0\.1|localhost|\[::1\])(?:[:/]|$)|(?!(?:[a-z][a-z0-9+.-]*:)?//))",
                    re.IGNORECASE)
_CSS_URL = re.compile(r"""(?:url\(\s*['"]?|@import\s+['"])([^'")\s]+)""", re.IGNORECASE)
#: The attributes a browser fetches on its own, per tag.
_FETCHED = {"script": ("src",), "img": ("src", "srcset"), "iframe": ("src",), "source": ("src", "srcset"),
            "audio": ("src",), "video": ("src", "poster"), "embed": ("src",), "object": ("data",)}
_FETCHED_LINKS = ("stylesheet", "preload", "preconnect", "dns-prefetch", "icon", "manifest", "modulepreload",
                  "prefetch")


def _external(url: str) -> bool:
    url = url.strip()
    return bool(url) and not url.startswith("data:") and not _LOCAL.match(url)


#: Markup that makes the theme's bundled script fetch from elsewhere: (tag, attribute, word) -> what it fetches.
_SCRIPT_FETCHES = {("pre", "class", "mermaid"): "https://unpkg.com/mermaid (a mermaid diagram)",
                   ("div", "class", "mermaid"): "https://unpkg.com/mermaid (a mermaid diagram)",
                   ("a", "data-md-component", "source"): "https://api.github.com (the repo_url source button)"}


class _Tags(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.found: list[str] = []
        self._style = False

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        values = {k: v or "" for k, v in attrs}
        for (kind, name, word), fetched in _SCRIPT_FETCHES.items():
            if tag == kind and word in values.get(name, "").split() and fetched not in self.found:
                self.found.append(fetched)
        if tag == "link" and any(r in values.get("rel", "").lower().split() for r in _FETCHED_LINKS):
            self.found.append(values.get("href", ""))
        for name in _FETCHED.get(tag, ()):
            if name in values:
                self.found.extend(part.split()[0] for part in values[name].split(",") if part.strip())
        if "style" in values:
            self.found.extend(_CSS_URL.findall(values["style"]))
        self._style = tag == "style"

    def handle_data(self, data: str) -> None:
        if self._style:
            self.found.extend(_CSS_URL.findall(data))

    def handle_endtag(self, tag: str) -> None:
        self._style = False


def external_requests(site: Path) -> dict[str, list[str]]:
    """``{file: [external URLs it would load]}`` for every HTML and CSS file of ``site``."""
    out: dict[str, list[str]] = {}
    for path in sorted(site.rglob("*")):
        if path.suffix == ".html":
            parser = _Tags()
            parser.feed(path.read_text(encoding="utf-8", errors="replace"))
            urls = parser.found
        elif path.suffix == ".css":
            urls = _CSS_URL.findall(path.read_text(encoding="utf-8", errors="replace"))
        else:
            continue
        bad = [u for u in urls if _external(u)]
        if bad:
            out[str(path.relative_to(site))] = bad
    return out


if __name__ == "__main__":  # python tests/newcomer/site_requests.py site  (nox -s docs runs it after the build)
    import sys

    found = external_requests(Path(sys.argv[1] if len(sys.argv) > 1 else "site"))
    for page, urls in found.items():
        print(f"{page}: loads {', '.join(urls)}", file=sys.stderr)
    sys.exit(1 if found else 0)
