"""``agentsctl --help`` and every command's help read as plain text: no reST markup from docstrings."""

from __future__ import annotations

import pytest

typer_testing = pytest.importorskip("typer.testing")

COMMANDS = [(), ("run",), ("ui",), ("router",), ("call",), ("topics",), ("topics", "list"), ("topics", "echo"),
            ("topics", "pub"), ("topics", "hz"), ("components",), ("components", "list"),
            ("components", "status"), ("components", "transition")]


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: " ".join(c) or "agentsctl")
def test_help_is_plain_text(command: tuple[str, ...]) -> None:
    from agents_core.cli.app import app  # noqa: PLC0415 - Typer is imported with the cli extra only

    if command == ("ui",):
        pytest.skip("'agentsctl ui --help' is the attach script's own argparse help (tested with the UI)")
    result = typer_testing.CliRunner().invoke(app, [*command, "--help"], env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    for markup in ("``", ":class:", ":func:", ":data:", ":meth:"):
        assert markup not in result.output, f"{markup!r} in the help of {' '.join(command)}:\n{result.output}"


def test_call_help_shows_the_payload() -> None:
    from agents_core.cli.app import app  # noqa: PLC0415

    result = typer_testing.CliRunner().invoke(app, ["call", "--help"], env={"COLUMNS": "200"})
    assert '"method"' in result.output and '"kwargs"' in result.output


def test_top_level_help_lists_every_command() -> None:
    from agents_core.cli.app import app  # noqa: PLC0415

    output = typer_testing.CliRunner().invoke(app, ["--help"], env={"COLUMNS": "200"}).output
    for name in ("run", "topics", "components", "call", "ui", "router"):
        assert name in output
