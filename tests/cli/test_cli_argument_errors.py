"""Arguments that used to end in tracebacks (deep JSON, huge numbers, absurd windows) end in one line.

Each case runs the real command tree in-process (Typer's runner): the value is refused before
any transport is opened, so no recipe is needed. Exit status 2 is a usage error (ours or Typer's).
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from agents_core.cli.values import (
    MAX_JSON_DEPTH,
    ArgumentError,
    parse_call_argument,
    parse_json_argument,
    parse_value,
)
from agents_core.supported_types import get_type
from tests.cli.helpers import REPO, cli_env

typer_testing = pytest.importorskip("typer.testing")

DEEP = "[" * 30_000 + "]" * 30_000
BIG = "1" + "0" * 400  # 10**400
HUGE = "1" + "0" * 5000  # beyond Python's 4300-digit int parsing limit


def _run(*args: str) -> tuple[int, str, BaseException | None]:
    from agents_core.cli.app import app  # noqa: PLC0415 - Typer is imported with the cli extra only

    result = typer_testing.CliRunner().invoke(app, list(args))
    return result.exit_code, result.stderr, result.exception


@pytest.mark.parametrize(("args", "message"), [
    (("call", "talker", "set_word", DEEP), "argument 1 ('[[[[[[[[[[[[[[[[[[[[...') nests arrays/objects 30000"),
    (("call", "talker", "set_word", "ok", BIG), "argument 2 ('10000000000000000000...') holds the integer"),
    (("call", "talker", "set_word", HUGE), "does not fit in 64 bits"),
    (("call", "talker", "set_word", "1e400"), "argument 1 ('1e400') holds the number 1e400, which is too large"),
    (("call", "talker", "set_word", "--kwargs", '{"a": ' + DEEP + "}"), "--kwargs nests arrays/objects 30001"),
    (("call", "talker", "set_word", "--kwargs", '{"a": ' + BIG + "}"), "--kwargs holds the integer"),
    (("call", "talker", "set_word", "--kwargs", "[1]"), "--kwargs must be a JSON object"),
    (("topics", "pub", "cmd", "Twist", '{"linear": ' + DEEP + "}"), "does not fit Twist: it nests arrays/objects"),
    (("topics", "pub", "n", "Float32", BIG), "does not fit Float32: it holds the integer"),
    (("topics", "pub", "n", "Float64", BIG), "does not fit Float64: it holds the integer"),
    (("topics", "pub", "n", "Float32", "1e39"), "Float32 value 1e+39 overflows float32"),
    (("topics", "pub", "n", "Int64", HUGE), "does not fit Int64"),
])
def test_bad_argument_values_are_one_line_usage_errors(args: tuple[str, ...], message: str) -> None:
    code, err, exception = _run(*args)
    assert isinstance(exception, SystemExit), exception  # no traceback: an exit with a message
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], err
    assert len(lines[0]) < 400  # the value is quoted shortened, never whole


@pytest.mark.parametrize(("option", "value"), [
    ("--window", "1e308"), ("--window", "inf"), ("--window", "nan"), ("--window", "-1"),
])
def test_hz_window_out_of_range_is_a_usage_error(option: str, value: str) -> None:
    code, err, exception = _run("topics", "hz", "chatter", option, value)
    assert isinstance(exception, SystemExit) and code == 2, (exception, err)
    assert "--window" in err and "Traceback" not in err


def test_pub_wait_out_of_range_is_a_usage_error() -> None:
    code, err, exception = _run("topics", "pub", "words", "String", "hi", "--wait", "1e308")
    assert isinstance(exception, SystemExit) and code == 2 and "--wait" in err, (exception, err)


def test_the_console_script_prints_no_traceback_for_deep_json() -> None:
    """The same through ``python -m agents_core.cli``: exit status 2, one line on stderr, nothing else."""
    done = subprocess.run([sys.executable, "-m", "agents_core.cli", "call", "talker", "set_word", DEEP],
                          cwd=REPO, env=cli_env(), capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 2 and done.stdout == "", done.stderr[-2000:]
    assert done.stderr.count("\n") == 1 and "nests arrays/objects 30000 levels deep" in done.stderr


def test_json_arguments_are_bounded_but_ordinary_ones_pass() -> None:
    nested = "[" * MAX_JSON_DEPTH + "]" * MAX_JSON_DEPTH
    assert parse_json_argument(nested, "x") == json.loads(nested)
    with pytest.raises(ArgumentError, match=f"{MAX_JSON_DEPTH + 1} levels deep"):
        parse_json_argument("[" + nested + "]", "x")
    # Brackets inside strings are text, not nesting.
    assert parse_json_argument('["' + "[" * 500 + '"]', "x") == ["[" * 500]
    assert parse_json_argument(str(2**64 - 1), "x") == 2**64 - 1
    assert parse_json_argument(str(-(2**63)), "x") == -(2**63)
    with pytest.raises(ArgumentError, match="does not fit in 64 bits"):
        parse_json_argument(str(2**64), "x")
    with pytest.raises(ArgumentError, match="is 1000001 characters long"):
        parse_json_argument(" " * 1_000_001, "x")
    assert parse_json_argument("1e308", "x") == 1e308
    # Not JSON at all: a call argument is then the text itself.
    assert parse_call_argument("[[[ not json") == "[[[ not json"


def test_a_string_topic_takes_text_that_would_be_out_of_bounds_as_json() -> None:
    assert parse_value(get_type("String"), DEEP) == DEEP
    assert parse_value(get_type("String"), BIG) == BIG
    assert parse_value(get_type("String"), "1e400") == "1e400"
