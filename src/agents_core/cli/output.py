"""Printing: Rich tables for people, ``--json`` documents for scripts, and network text shown as text.

Everything the CLI prints may come from the network (topic values, names, describe replies,
call results, remote error messages), so nothing is ever given to Rich as markup: a ``[/INST]``
in an LLM's answer would crash the markup parser and ``[bold red]`` would restyle the output.
Text goes through :func:`safe_text`, which shows control characters escaped (``\\x1b``,
``\\u202e``) so that no escape sequence reaches the terminal (a window title, a cleared
screen, a hyperlink to any site) and no bidi override reorders what is shown, then into a
:class:`rich.text.Text`, which Rich prints as it is. ``--json`` output stays raw JSON:
``json.dumps`` escapes every control and non-ASCII character itself.
"""

from __future__ import annotations

import json
import logging
import re
from collections.abc import Sequence
from typing import Any

from rich.console import Console
from rich.pretty import pretty_repr
from rich.table import Table
from rich.text import Text

__all__ = [
    "SafeFormatter",
    "console",
    "install_safe_logging",
    "plain",
    "print_json",
    "print_table",
    "print_value",
    "safe_text",
    "say",
]

#: Wide enough that piped output keeps one row per line.
console = Console(width=160, highlight=False, markup=False, emoji=False)

# C0 controls but newline and tab, DEL, C1 controls (a lone 0x9b is CSI on some terminals), the
# line and paragraph separators, and the bidi marks, embeddings, overrides and isolates.
_UNSAFE = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u061c\u200e\u200f\u2028-\u202e\u2066-\u2069]")
_UNSAFE_IN_LINE = re.compile("[\x00-\x1f\x7f-\x9f\u061c\u200e\u200f\u2028-\u202e\u2066-\u2069]")


def _escape(match: re.Match[str]) -> str:
    code = ord(match.group())
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def safe_text(value: object, *, one_line: bool = False) -> str:
    """``str(value)`` with every control character shown escaped (``\\x1b``), safe to print to a terminal.

    Newlines and tabs are kept unless ``one_line`` (then they are escaped too).
    """
    text = value if isinstance(value, str) else str(value)
    return (_UNSAFE_IN_LINE if one_line else _UNSAFE).sub(_escape, text)


def plain(value: object, style: str = "") -> Text:
    """``value`` as a Rich :class:`~rich.text.Text` (never parsed as markup), control characters escaped."""
    return Text(safe_text(value), style=style)


def say(*parts: object | tuple[object, str]) -> None:
    """Print one line assembled from ``parts``: values, or ``(value, style)`` pairs; none is markup."""
    line = Text()
    for part in parts:
        if isinstance(part, tuple):
            line.append(safe_text(part[0]), style=part[1])
        else:
            line.append(safe_text(part))
    console.print(line)


def print_value(doc: Any) -> None:
    """A summarised value (:func:`agents_core.cli.values.summarize`): a string as text, anything else as its repr."""
    console.print(plain(doc if isinstance(doc, str) else pretty_repr(doc)))


def print_json(doc: Any) -> None:
    """One JSON document on one line of stdout."""
    print(json.dumps(doc, default=str), flush=True)


def print_table(title: str, columns: Sequence[str], rows: Sequence[Sequence[Any]]) -> None:
    """A Rich table with ``columns`` and one row per item (a note instead when there are none)."""
    if not rows:
        say(title, ": none")
        return
    table = Table(title=plain(title), title_justify="left")
    for column in columns:
        table.add_column(plain(column))
    for row in rows:
        table.add_row(*(plain(cell) for cell in row))
    console.print(table)


class SafeFormatter(logging.Formatter):
    """A log formatter whose lines show control characters escaped (log messages may quote remote text)."""

    def format(self, record: logging.LogRecord) -> str:
        """The formatted record, through :func:`safe_text`."""
        return safe_text(super().format(record))


def install_safe_logging(level: int = logging.WARNING) -> None:
    """Send warnings (and worse) to stderr through :class:`SafeFormatter`, unless logging is configured already.

    Without a handler, Python's last-resort one would print a library's warning that quotes a
    remote's text (a state that does not decode, a bad reply) with its escape sequences intact.
    """
    root = logging.getLogger()
    if root.handlers:
        return
    handler = logging.StreamHandler()
    handler.setFormatter(SafeFormatter("%(levelname)s %(name)s: %(message)s"))
    root.addHandler(handler)
    root.setLevel(level)
