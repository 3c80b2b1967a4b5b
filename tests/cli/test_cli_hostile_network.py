"""``agentsctl`` against a hostile peer: every command prints what the network sends as text.

``tests/cli/hostile_recipe.py`` runs in its own process on Zenoh and answers every command with
Rich markup (``[/INST]``, ``[bold red]``), terminal escapes (OSC 0 title, CSI 2J clear, an OSC 8
link) and a bidi override, in topic values, topic and component names, type names, describe
replies, states, call results and remote errors. Each command runs as ``python -m
agents_core.cli`` in a subprocess: it must exit as it would for friendly text, print no
traceback, show the text with its control characters escaped, and let no raw ESC (or bidi
override) reach the terminal; ``--json`` output still parses and carries the text unchanged.
"""

from __future__ import annotations

import json
import subprocess
from collections.abc import Iterator

import pytest

from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.pairs import missing_requirement
from tests.cli.helpers import cli, cli_env, start, stop, wait_until
from tests.cli.hostile_recipe import HOSTILE

pytestmark = [pytest.mark.slow, pytest.mark.zenoh,
              pytest.mark.skipif(missing_requirement("zenoh") is not None, reason=str(missing_requirement("zenoh")))]

#: What the hostile text must look like once printed: its markup literal, its escapes spelled out
#: (pieces without spaces, since tables wrap long cells at spaces).
SHOWN = ("[/INST]", "[bold", "red]RED[/bold", "\\x1b]0;pwned\\x07", "\\x1b[2J", "\\x1b]8;;http", "\\u202eevil")
#: What must never reach the terminal.
RAW = ("\x1b", "\x07", "\u202e", "\x9b")


@pytest.fixture(scope="module")
def options(tmp_path_factory: pytest.TempPathFactory) -> Iterator[list[str]]:
    """The options that reach the hostile recipe (started once for the module)."""
    log = tmp_path_factory.mktemp("cli-hostile") / "recipe.log"
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    process = start("run", "tests/cli/hostile_recipe.py", "--transport", "zenoh",
                    env=cli_env(AGENTS_ZENOH_LISTEN=endpoint), log=log)
    options = ["--transport", "zenoh", "--connect", endpoint]
    try:
        def ready() -> bool:
            assert process.poll() is None, log.read_text()
            done = cli("components", "list", "--json", *options)
            return done.returncode == 0 and {"parrot", "imposter"} <= {c["name"] for c in json.loads(done.stdout)}
        assert wait_until(ready, timeout=90.0), log.read_text()
        yield options
    finally:
        stop(process)


def _check_printed_as_text(done: subprocess.CompletedProcess[str], code: int = 0) -> str:
    both = done.stdout + done.stderr
    assert done.returncode == code, both[-3000:]
    assert "Traceback" not in both and "MarkupError" not in both, both[-3000:]
    for raw in RAW:
        assert raw not in both, f"{raw!r} reached the terminal: {both[-3000:]!r}"
    return both


@pytest.mark.parametrize("args", [
    ("topics", "list"),
    ("topics", "echo", "llm_answer", "--count", "1"),
    ("components", "list"),
    ("components", "status", "imposter"),
    ("components", "status", "parrot"),
    ("components", "transition", "imposter", "activate"),
    ("call", "parrot", "say"),
    ("call", "imposter", "anything"),
], ids=" ".join)
def test_every_command_prints_network_text_as_text(options: list[str], args: tuple[str, ...]) -> None:
    both = _check_printed_as_text(cli(*args, *options))
    for piece in SHOWN:
        assert piece in both, f"{piece!r} not shown in {both[-3000:]}"


@pytest.mark.parametrize(("args", "message"), [
    (("call", "parrot", "fail"), "RuntimeError: LLM says [/INST] [bold red]RED[/bold red] \\x1b]0;pwned\\x07"),
    (("topics", "echo", "oddly_typed", "--timeout", "2"), "carries LLM says [/INST] [bold red]RED[/bold red]"),
], ids=["remote error", "hostile type name"])
def test_remote_text_in_errors_is_one_escaped_line(options: list[str], args: tuple[str, ...], message: str) -> None:
    done = cli(*args, *options)
    _check_printed_as_text(done, code=1)
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], done.stderr


def test_escapes_without_markup_are_shown_escaped(options: list[str]) -> None:
    done = cli("topics", "echo", "escapes_only", "--count", "1", *options)
    _check_printed_as_text(done)
    assert "\\x1b]0;pwned\\x07 \\x1b[2J \\x1b]8;;http://evil\\x1b\\link" in done.stdout


def test_hostile_names_do_not_break_the_component_list(options: list[str]) -> None:
    done = cli("components", "list", *options)
    _check_printed_as_text(done)
    assert "parrot" in done.stdout and "active" in done.stdout  # the friendly component is still listed


@pytest.mark.parametrize("args", [
    ("topics", "list"),
    ("topics", "echo", "llm_answer", "--count", "1"),
    ("components", "list"),
    ("components", "status", "imposter"),
    ("call", "imposter", "anything"),
], ids=" ".join)
def test_json_output_stays_raw_json(options: list[str], args: tuple[str, ...]) -> None:
    done = cli(*args, "--json", *options)
    _check_printed_as_text(done)  # json.dumps escapes control characters itself
    assert HOSTILE in _strings([json.loads(line) for line in done.stdout.splitlines()])


def _strings(doc: object) -> list[str]:
    """Every string in a JSON document, keys included."""
    if isinstance(doc, str):
        return [doc]
    if isinstance(doc, dict):
        return [s for k, v in doc.items() for s in (*_strings(k), *_strings(v))]
    if isinstance(doc, list):
        return [s for item in doc for s in _strings(item)]
    return []


def test_the_recipe_is_hostile(options: list[str]) -> None:
    """The probe itself: its text really carries what the other tests expect to be neutralised."""
    done = cli("call", "imposter", "anything", "--json", *options)
    assert json.loads(done.stdout)["result"]["answer"] == HOSTILE
    assert all(raw in HOSTILE for raw in ("\x1b]0;", "\x1b[2J", "\x1b]8;;", "\u202e", "[/INST]"))
