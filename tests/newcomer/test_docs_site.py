"""Item 5 of issue 38: the documentation site as a new user opens it.

- the configuration reference lists every component config with the defaults the classes really have
  (no "required" for a field with a default), built from the source by docs/hooks/config_reference.py;
- the site (``mkdocs build --strict``, as ``nox -s docs``) opens on a short home page with the tutorial
  path, not the whole README; MLLM's task table and the Event page are there; and no page loads anything
  from another machine (fonts, scripts, styles). The build runs where ``mkdocs`` is installed (the docs
  extra; ``AGENTS_MKDOCS`` may name the executable) and is skipped, saying so, elsewhere.
"""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
from pathlib import Path
from types import ModuleType

import attrs
import pytest

from tests.newcomer.site_requests import external_requests

REPO = Path(__file__).resolve().parents[2]
CONFIG_FILES = [
    "src/agents_core/config.py",
    "src/agents_core/components/llm_config.py",
    "src/agents_core/components/mllm_config.py",
    "src/agents_core/components/semantic_router_config.py",
    "src/agents_core/components/map_encoding_config.py",
    "src/agents_core/components/vision/config.py",
    "src/agents_core/components/video_maker_config.py",
    "src/agents_core/components/speech_to_text_config.py",
    "src/agents_core/components/text_to_speech_config.py",
    "src/agents_core/components/vla/config.py",
    "src/agents_core/components/memory/config.py",
    "src/agents_core/components/cortex/config.py",
]


def _hook() -> ModuleType:
    spec = importlib.util.spec_from_file_location("config_reference_hook", REPO / "docs/hooks/config_reference.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _rows(markdown: str) -> dict[str, dict[str, str]]:
    """``{class: {field: default cell}}`` of the generated reference."""
    out: dict[str, dict[str, str]] = {}
    current = ""
    for line in markdown.splitlines():
        if line.startswith("### "):
            current = line[4:].strip()
            out[current] = {}
        found = re.match(r"^\| `(\w+)` \| .*? \| (required|`.*?`) \| ", line)
        if found and current:
            out[current][found.group(1)] = found.group(2)
    return out


def _expected(default: object) -> str:
    if isinstance(default, attrs.Factory):  # type: ignore[arg-type]
        made = default.factory()  # type: ignore[attr-defined]
        return f"`{made!r}`" if isinstance(made, dict | list | tuple | set) else "factory"
    return f"`{default!r}`"


def test_the_config_reference_shows_each_fields_real_default() -> None:
    from agents_core import config  # noqa: PLC0415

    rows = _rows(_hook().config_sections(REPO, CONFIG_FILES))
    names = [n for n in config.__all__ if n.endswith("Config") and n != "VLMConfig"]
    assert set(names) <= set(rows), f"missing from the reference: {sorted(set(names) - set(rows))}"
    checked = 0
    for name in names:
        cls = getattr(config, name)
        own = {a.name: a for a in attrs.fields(cls) if a.name in rows[name]}
        for field_name, attribute in own.items():
            shown = rows[name][field_name]
            if attribute.default is attrs.NOTHING:
                assert shown == "required", (name, field_name, shown)
                continue
            want = _expected(attribute.default)
            if want != "factory":
                assert shown == want.replace("|", "\\|"), (name, field_name, shown, want)
            checked += 1
    assert checked > 100
    assert rows["LLMConfig"]["temperature"] == "`0.8`"


def test_the_request_check_sees_web_fonts(tmp_path: Path) -> None:
    (tmp_path / "index.html").write_text(
        '<link rel="preconnect" href="https://fonts.gstatic.com"><link rel="stylesheet" href="assets/x.css">'
        '<a href="https://example.org/">a link is not a request</a><script src="//cdn.example.net/a.js"></script>')
    (tmp_path / "x.css").write_text("@import 'https://fonts.googleapis.com/css?family=Roboto'; a{b:url(y.png)}")
    (tmp_path / "diagram.html").write_text('<pre class="mermaid"><code>graph LR; a-->b</code></pre>'
                                           '<a href="https://github.com/x/y" class="md-source" '
                                           'data-md-component="source">x/y</a>')
    found = external_requests(tmp_path)
    assert found == {"index.html": ["https://fonts.gstatic.com", "//cdn.example.net/a.js"],
                     "diagram.html": ["https://unpkg.com/mermaid (a mermaid diagram)",
                                      "https://api.github.com (the repo_url source button)"],
                     "x.css": ["https://fonts.googleapis.com/css?family=Roboto"]}


def _mkdocs() -> str:
    found = os.environ.get("AGENTS_MKDOCS") or shutil.which("mkdocs")
    if not found:
        pytest.skip("mkdocs is not installed (the docs extra; nox -s docs builds the site)")
    return found


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("site")
    done = subprocess.run([_mkdocs(), "build", "--strict", "--site-dir", str(out)], cwd=REPO, capture_output=True,
                          text=True, timeout=600, check=False, env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    assert done.returncode == 0, done.stderr[-4000:]
    return out


def test_the_site_loads_nothing_from_elsewhere(site: Path) -> None:
    assert external_requests(site) == {}


def test_the_home_page_is_the_tutorial_path_not_the_readme(site: Path) -> None:
    home = (site / "index.html").read_text()
    for page in ("install", "first-recipe", "custom-component", "testing", "processes", "transports"):
        assert f'href="tutorial/{page}/"' in home, page
    assert "Installing" not in home and (site / "readme" / "index.html").is_file()


def test_the_reference_pages_show_defaults_tasks_and_events(site: Path) -> None:
    config = (site / "api" / "config" / "index.html").read_text()
    llm = config.split('id="llmconfig"', 1)[1].split("<h3", 1)[0]
    assert "<td><code>temperature</code></td>\n<td>float</td>\n<td><code>0.8</code></td>" in llm
    assert "required" not in llm
    components = (site / "api" / "components" / "index.html").read_text()
    assert "<td>grounding</td>" in components and "<td>PointsOfInterest</td>" in components
    events = (site / "events-and-actions" / "index.html").read_text()
    assert "keep_event_delay" in events and "on_change" in events and "execute_method" in events
