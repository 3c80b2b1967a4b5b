"""The CLI's printing shows network text as text: no Rich markup, control characters escaped."""

from __future__ import annotations

import logging

import pytest

from agents_core.cli.connection import fail, one_line_errors
from agents_core.cli.output import SafeFormatter, plain, print_table, print_value, safe_text, say

HOSTILE = ("[/INST] [bold red]RED[/bold red] \x1b]0;pwned\x07 \x1b[2J \x1b]8;;http://evil\x1b\\link\x1b]8;;\x1b\\ "
           "\u202eevil")
SHOWN = ("[/INST] [bold red]RED[/bold red] \\x1b]0;pwned\\x07 \\x1b[2J \\x1b]8;;http://evil\\x1b\\link\\x1b]8;;\\x1b\\ "
         "\\u202eevil")
#: Never printed raw: ESC, BEL, CR, NUL, DEL, C1 CSI, line separator, bidi marks, overrides and isolates.
UNSAFE = ("\x1b\x07\r\x00\x7f\x9b\x85\u2028\u2029"
          "\u061c\u200e\u200f\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069")


def test_safe_text_escapes_control_characters_and_keeps_the_rest() -> None:
    assert safe_text(HOSTILE) == SHOWN
    escaped = safe_text(UNSAFE)
    assert not any(ch in escaped for ch in UNSAFE)
    assert escaped.startswith("\\x1b\\x07\\x0d\\x00\\x7f\\x9b\\x85\\u2028")
    kept = "plain [markup] text, accents é, CJK 漢字, emoji 🤖, quotes \"'\\"
    assert safe_text(kept) == kept
    assert safe_text("two\nlines\tand a tab") == "two\nlines\tand a tab"
    assert safe_text("two\nlines\tand a tab", one_line=True) == "two\\x0alines\\x09and a tab"
    assert safe_text(42) == "42"


def _printed(capsys: pytest.CaptureFixture[str]) -> str:
    out, err = capsys.readouterr()
    assert not any(ch in out + err for ch in "\x1b\x07\u202e"), repr(out + err)
    return out


def test_printing_never_interprets_markup(capsys: pytest.CaptureFixture[str]) -> None:
    print_value(HOSTILE)
    assert _printed(capsys).strip() == SHOWN.strip()

    print_value({"answer": HOSTILE, HOSTILE: [1, HOSTILE]})
    out = _printed(capsys)
    assert "[/INST]" in out and "\\x1b[2J" in out and "\\u202eevil" in out

    say((HOSTILE, "bold"), " and ", HOSTILE)
    assert _printed(capsys).count("[bold red]RED[/bold red]") == 2

    print_table(HOSTILE, ["[/INST]", "value"], [(HOSTILE, HOSTILE), ("[bold]", 3)])
    out = _printed(capsys)
    assert "[/INST]" in out and "[bold]" in out and "\\x1b]0;pwned\\x07" in out

    print_table(f"none {HOSTILE}", ["a"], [])
    assert "[/INST]" in _printed(capsys)

    assert plain("[bold]x").plain == "[bold]x"


def test_fail_prints_one_escaped_line(capsys: pytest.CaptureFixture[str]) -> None:
    code = fail(f"remote said:\n{HOSTILE}\r\n  more")
    assert code.exit_code == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "\x1b" not in err and "\u202e" not in err
    assert err.startswith("error: remote said: [/INST] [bold red]RED[/bold red] \\x1b]0;pwned\\x07")


def test_log_lines_are_escaped() -> None:
    record = logging.LogRecord("agents_zenoh", logging.WARNING, __file__, 1, "state %s", (HOSTILE,), None)
    line = SafeFormatter("%(message)s").format(record)
    assert line == f"state {SHOWN}"


@pytest.mark.parametrize(("error", "code", "message"), [
    (OverflowError("int too large to convert to float"), 1, "error: int too large to convert to float"),
    (RecursionError("maximum recursion depth exceeded"), 1, "error: a value is nested too deeply to handle"),
    (ValueError(HOSTILE), 1, f"error: {SHOWN.strip()}"),
])
def test_one_line_errors_catch_what_user_input_can_raise(capsys: pytest.CaptureFixture[str], error: Exception,
                                                         code: int, message: str) -> None:
    @one_line_errors
    def command() -> None:
        raise error

    import typer  # noqa: PLC0415 - the cli extra, as the modules above

    with pytest.raises(typer.Exit) as exited:
        command()
    assert exited.value.exit_code == code
    assert capsys.readouterr().err.strip() == message
