"""The documentation site's MkDocs hooks (docs/hooks/docs_site.py), without MkDocs: includes, links, warnings."""

from __future__ import annotations

import importlib.util
import logging
import textwrap
from pathlib import Path
from types import ModuleType, SimpleNamespace

import pytest

REPO = Path(__file__).resolve().parent.parent


def _load_hooks() -> ModuleType:
    spec = importlib.util.spec_from_file_location("docs_site_hooks", REPO / "docs" / "hooks" / "docs_site.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


hooks = _load_hooks()


def _page(src_uri: str) -> SimpleNamespace:
    return SimpleNamespace(file=SimpleNamespace(src_uri=src_uri))


def _config(repo_url: str | None = None) -> dict[str, object]:
    return {"config_file_path": str(REPO / "mkdocs.yml"), "repo_url": repo_url}


def test_readme_links_are_rewritten_for_the_site_home() -> None:
    readme = ("See [porting](docs/porting.md#the-one-change), [talker.py](examples/talker.py), "
              "[up](https://github.com/k2-fsa/sherpa-onnx) and [here](#installing).\n"
              "```python\nx = [a](docs/cli.md)\n```\n")
    out = hooks._rewrite_links(readme, "README.md", "index.md", None)
    assert "[porting](porting.md#the-one-change)" in out
    assert "talker.py, " in out and "(examples/talker.py)" not in out  # outside docs/: its text only
    assert "[up](https://github.com/k2-fsa/sherpa-onnx)" in out and "[here](#installing)" in out
    assert "x = [a](docs/cli.md)" in out  # code is left as written
    with_repo = hooks._rewrite_links(readme, "README.md", "index.md", "https://github.com/me/agents-core/")
    assert "[talker.py](https://github.com/me/agents-core/blob/main/examples/talker.py)" in with_repo


def test_links_of_a_file_in_a_subfolder_resolve_from_there() -> None:
    out = hooks._rewrite_links("[cli](../docs/cli.md) [run](run.py)", "benchmarks/README.md", "benchmarks.md", None)
    assert out == "[cli](cli.md) run"


def test_an_include_page_becomes_the_file_and_a_missing_file_is_a_warning(caplog: pytest.LogCaptureFixture) -> None:
    out = hooks.on_page_markdown("<!-- include: README.md -->\nthe GitHub view's text\n", _page("index.md"),
                                 _config(), None)
    assert out.startswith("# agents-core") and "the GitHub view's text" not in out
    assert "](docs/" not in out, "README links into docs/ are rewritten"
    mentioned = "text that shows `<!-- include: README.md -->` as an example\n"
    assert hooks.on_page_markdown(mentioned, _page("writing-docs.md"), _config(), None) == mentioned
    with caplog.at_level(logging.WARNING):
        hooks.on_page_markdown("<!-- include: NOPE.md -->\n", _page("index.md"), _config(), None)
    assert "NOPE.md, which does not exist" in caplog.text


def test_external_links_are_checked_offline(caplog: pytest.LogCaptureFixture) -> None:
    fine = ("[a](https://pypi.org/project/emem/) [ui](http://127.0.0.1:5001/) [l](http://localhost:8000)\n"
            "```bash\ncurl http://example.com\n```\n")
    with caplog.at_level(logging.WARNING):
        hooks.on_page_markdown(fine, _page("ui.md"), _config(), None)
    assert not caplog.records
    with caplog.at_level(logging.WARNING):
        hooks.on_page_markdown("[plain](http://example.com/x) [bare](https://intranet/)", _page("ui.md"),
                               _config(), None)
    assert "http://example.com/x" in caplog.text and "https://intranet/" in caplog.text


def _griffe_record(path: Path, line: int, message: str) -> logging.LogRecord:
    return logging.LogRecord("mkdocs.plugins.griffe", logging.WARNING, __file__, 0,
                             f"griffe: {path}:{line}: {message}", None, None)


def test_unknown_parameter_warnings_are_dropped_only_for_generated_inits(tmp_path: Path) -> None:
    source = tmp_path / "module.py"
    source.write_text(textwrap.dedent('''\
        from attrs import define


        @define(kw_only=True)
        class Fields:
            """Fields.

            :param size: how big.
            """

            size: int = 1


        class Passes(Base):
            """Passes its arguments on.

            :param timeout: seconds.
            """

            rate = 2


        class Own:
            """Its own __init__.

            :param stale: gone.
            """

            def __init__(self) -> None:
                pass


        def function(x):
            """A function.

            :param stale: gone.
            """
        '''), encoding="utf-8")
    keep = hooks._AttrsInitParameters().filter
    for line, expected in ((6, False), (15, False), (24, True), (33, True)):
        for message in ("No matching parameter for 'x'", "Parameter 'x' does not appear in the function signature"):
            assert keep(_griffe_record(source, line, message)) is expected, (line, message)
    assert keep(_griffe_record(source, 6, "Failed to get 'name: description' pair from 'oops'"))


def test_sphinx_roles_become_optional_references() -> None:
    html = ("Alias of :attr:<code>component_name</code>; see :class:<code>~agents_core.topics.Topic</code> "
            "and :func:<code>wait_for()</code>; :class:<code>not a name</code>")
    out = hooks._roles_to_references(html)
    assert '<autoref identifier="component_name" optional><code>component_name</code></autoref>' in out
    assert '<autoref identifier="agents_core.topics.Topic" optional><code>Topic</code></autoref>' in out
    assert '<autoref identifier="wait_for" optional><code>wait_for</code></autoref>' in out
    assert "<code>not a name</code>" in out and ":class:" not in out
