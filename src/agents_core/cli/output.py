"""Printing: Rich tables for people, ``--json`` documents for scripts."""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any

from rich.console import Console
from rich.table import Table

__all__ = ["console", "print_json", "print_table"]

#: Wide enough that piped output keeps one row per line.
console = Console(width=160, highlight=False)


def print_json(doc: Any) -> None:
    """One JSON document on one line of stdout."""
    print(json.dumps(doc, default=str), flush=True)


def print_table(title: str, columns: Sequence[str], rows: Sequence[Sequence[Any]]) -> None:
    """A Rich table with ``columns`` and one row per item (a note instead when there are none)."""
    if not rows:
        console.print(f"{title}: none")
        return
    table = Table(title=title, title_justify="left")
    for column in columns:
        table.add_column(column)
    for row in rows:
        table.add_row(*(str(cell) for cell in row))
    console.print(table)
