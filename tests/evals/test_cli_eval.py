"""``agentsctl eval report`` and ``agentsctl eval compare``: what they print, write, and the exit status CI gates on."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents_core.evals.compare import compare_runs

from ..cli.helpers import cli
from .results_dirs import make_run

typer_testing = pytest.importorskip("typer.testing", reason="the cli extra is not installed")


def _invoke(*args: str) -> tuple[int, str]:
    from agents_core.cli.app import app  # noqa: PLC0415 - Typer is imported with the cli extra only

    result = typer_testing.CliRunner().invoke(app, list(args), env={"COLUMNS": "200"})
    return result.exit_code, result.output


def test_report_writes_the_page_and_prints_a_summary(tmp_path: Path) -> None:
    out = make_run(tmp_path / "run", [True] * 16 + [False] * 4)
    code, output = _invoke("eval", "report", str(out))
    assert code == 0, output
    assert (out / "report.html").is_file() and f"report: {out / 'report.html'}" in output
    assert "16" in output and "80.0 %" in output and "58.4-91.9 %" in output
    assert "failed seeds: 16, 17, 18, 19" in output


def test_report_json_and_a_hostile_name_in_a_terminal(tmp_path: Path) -> None:
    out = make_run(tmp_path / "run", [True, False], name="\x1b]0;owned\x07\x1b[31mred")
    code, output = _invoke("eval", "report", str(out))
    assert code == 0 and "\x1b" not in output and "\\x1b" in output  # shown escaped, never sent to the terminal
    code, output = _invoke("eval", "report", str(out), "--json")
    doc = json.loads(output)
    assert (doc["successes"], doc["episodes"], doc["success_rate"], doc["failed_seeds"]) == (1, 2, 0.5, [1])
    assert doc["report"] == str(out / "report.html")


def test_report_of_a_directory_that_is_no_evaluation_exits_2(tmp_path: Path) -> None:
    code, output = _invoke("eval", "report", str(tmp_path))
    assert code == 2 and "evaluation.json does not exist" in output
    (tmp_path / "evaluation.json").write_text('{"name": "x"}')
    (tmp_path / "results.jsonl").write_text('{"episode": 0, "seed": "zero"}\n')
    code, output = _invoke("eval", "report", str(tmp_path))
    assert code == 2 and "line 1: field 'seed' must be an integer" in output


def test_compare_exits_1_only_when_b_is_significantly_worse(tmp_path: Path) -> None:
    good = make_run(tmp_path / "good", [True] * 18 + [False] * 2, name="main", frames=False)
    bad = make_run(tmp_path / "bad", [True] * 6 + [False] * 14, name="change", frames=False)
    close = make_run(tmp_path / "close", [True] * 16 + [False] * 4, name="close", frames=False)
    code, output = _invoke("eval", "compare", str(good), str(bad))
    assert code == 1, output
    p = compare_runs(good, bad).p_value
    assert f"p = {p:.4g}" in output and "B is worse than A" in output and "90.0 %" in output and "30.0 %" in output
    code, output = _invoke("eval", "compare", str(bad), str(good))
    assert code == 0 and "B is better than A" in output
    code, output = _invoke("eval", "compare", str(good), str(close))
    assert code == 0 and "not significantly different" in output
    # A stricter alpha turns "worse" into "no significant difference" for a middling gap.
    middling = make_run(tmp_path / "mid", [True] * 10 + [False] * 10, frames=False)  # p = 0.014
    assert _invoke("eval", "compare", str(good), str(middling), "--alpha", "0.05")[0] == 1
    assert _invoke("eval", "compare", str(good), str(middling), "--alpha", "0.01")[0] == 0


def test_compare_writes_the_page_and_json(tmp_path: Path) -> None:
    a = make_run(tmp_path / "a", [True] * 10, frames=False)
    b = make_run(tmp_path / "b", [True] * 9 + [False], frames=False)
    page = tmp_path / "pages" / "compare.html"
    code, output = _invoke("eval", "compare", str(a), str(b), "--out", str(page), "--json")
    assert code == 0, output
    doc = json.loads(output)
    assert doc["verdict"] == "no significant difference" and doc["report"] == str(page) and page.is_file()
    assert doc["flipped"] == [{"seed": 9, "a": True, "b": False}] and doc["same_seeds"] is True
    assert doc["a"]["successes"] == 10 and doc["b"]["successes"] == 9


def test_compare_with_a_bad_directory_or_alpha_exits_2(tmp_path: Path) -> None:
    a = make_run(tmp_path / "a", [True], frames=False)
    assert _invoke("eval", "compare", str(a), str(tmp_path / "nope"))[0] == 2
    assert _invoke("eval", "compare", str(a), str(a), "--alpha", "2")[0] == 2


def test_the_exit_status_reaches_a_real_shell(tmp_path: Path) -> None:
    # What a CI step sees: the console entry point in its own process.
    good = make_run(tmp_path / "good", [True] * 19 + [False], frames=False)
    bad = make_run(tmp_path / "bad", [True] * 4 + [False] * 16, frames=False)
    worse = cli("eval", "compare", str(good), str(bad))
    assert worse.returncode == 1, worse.stderr
    assert "B is worse than A" in worse.stdout
    fine = cli("eval", "compare", str(bad), str(good))
    assert fine.returncode == 0, fine.stderr


@pytest.mark.parametrize("command", [("eval",), ("eval", "report"), ("eval", "compare")])
def test_help_is_plain_text(command: tuple[str, ...]) -> None:
    code, output = _invoke(*command, "--help")
    assert code == 0, output
    for markup in ("``", ":class:", ":func:", ":data:"):
        assert markup not in output
    if command == ("eval",):
        assert "report" in output and "compare" in output
    if command == ("eval", "compare"):
        assert "exit status 1" in output.lower()


def test_agentsctl_lists_eval() -> None:
    code, output = _invoke("--help")
    assert code == 0 and "eval" in output
