"""``agentsctl top``: a live table of every component of a running recipe (any cross-process transport).

It finds the components as ``agentsctl components list`` does (discovery through the transport,
``--connect`` for a router) and reads each one's ``<name>/status`` (:mod:`.top_rows`): state,
health, step rate, p50 / p99 step time, the last model call's latency, drops, restarts, CPU and
RSS of its process. The table refreshes in place (Rich ``Live``); keys sort it (``n`` name, ``r``
rate, ``5`` p50, ``9`` p99, ``m`` model, ``d`` drops, ``t`` restarts, ``c`` CPU, ``s`` RSS) and
``q`` quits (Ctrl-C too). ``--json`` prints the rows once and exits.
"""

from __future__ import annotations

import contextlib
import os
import select
import sys
import time
from collections.abc import Iterator
from typing import Annotated, Any

import typer
from rich.console import Console, Group
from rich.live import Live
from rich.table import Table
from rich.text import Text

from .connection import discovery_timeout, one_line_errors, open_transport
from .output import plain, print_json
from .top_rows import COLUMNS, SORT_KEYS, StatusBook
from .topics import ConnectOpt, DiscoveryOpt, JsonOpt, TransportOpt

__all__ = ["render", "top"]

#: Components are looked for again this often (new ones appear, stopped ones go).
REDISCOVER_S = 3.0
#: ``--json`` waits this long after the first status of each component (the recent ones arrive in order).
JSON_SETTLE_S = 0.5


def _cell(value: Any) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.1f}" if abs(value) >= 10 else f"{value:.2f}"
    return str(value)


def render(rows: list[dict[str, Any]], sort: str, where: str) -> Group:
    """The table and its key line."""
    table = Table(title=plain(f"agentsctl top: {len(rows)} component(s) on {where}"), title_justify="left")
    for header, _ in COLUMNS:
        table.add_column(plain(header), justify="left" if header in ("component", "state", "health") else "right")
    for row in rows:
        table.add_row(*(plain(_cell(row.get(key))) for _, key in COLUMNS))
    keys = " ".join(f"{k}:{field.split('_')[0]}" for k, (field, _) in SORT_KEYS.items())
    return Group(table, Text(f"sorted by {SORT_KEYS.get(sort, SORT_KEYS['n'])[0]}  |  keys: {keys}  q:quit"))


@contextlib.contextmanager
def _keys() -> Iterator[Any]:
    """Single key presses from a terminal (cbreak mode, restored after); None when stdin is not one."""
    if not sys.stdin.isatty():
        yield None
        return
    import termios  # noqa: PLC0415  (POSIX terminals)
    import tty  # noqa: PLC0415

    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd)
    tty.setcbreak(fd, termios.TCSANOW)  # keys typed ahead (a q during start-up) are kept
    try:
        yield fd
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)


def _read_key(fd: int | None, timeout: float) -> str | None:
    if fd is None:
        time.sleep(timeout)
        return None
    ready, _, _ = select.select([fd], [], [], timeout)
    if not ready:
        return None
    data = os.read(fd, 16)
    return data.decode("utf-8", "replace")[-1:] if data else "q"


@one_line_errors
def top(transport: TransportOpt = None, connect: ConnectOpt = None, json_out: JsonOpt = False,
        timeout: DiscoveryOpt = None,
        sort: Annotated[str, typer.Option("--sort", help=f"the first sort key: {', '.join(SORT_KEYS)}")] = "n",
        interval: Annotated[float, typer.Option("--interval", help="seconds between refreshes", min=0.1,
                                                max=60.0)] = 1.0) -> None:
    """A live table of every component of a running recipe; keys sort it, q quits (--json: print once)."""
    sort = sort if sort in SORT_KEYS else "n"
    with open_transport(transport, connect) as t:
        book = StatusBook(t)
        try:
            wait = discovery_timeout(t, timeout)
            book.discover(wait)
            if json_out:
                deadline = time.monotonic() + max(2.0, wait)
                while book.waiting() and time.monotonic() < deadline:
                    time.sleep(0.05)
                time.sleep(JSON_SETTLE_S)  # a late joiner gets the recent statuses in order: the last one wins
                print_json(book.rows(sort))
                return
            _live(book, sort, interval, t.name)
        finally:
            book.close()


def _live(book: StatusBook, sort: str, interval: float, where: str) -> None:
    console = Console()
    # A terminal that cannot redraw in place (TERM=dumb) or a pipe gets one table per refresh instead.
    in_place = console.is_terminal and not console.is_dumb_terminal
    last_discovery = time.monotonic()
    with _keys() as fd, (Live(render(book.rows(sort), sort, where), console=console, auto_refresh=False)
                         if in_place else contextlib.nullcontext()) as live:
        while True:
            key = _read_key(fd, interval)
            if key in ("q", "Q"):
                return
            if key in SORT_KEYS:
                sort = key
            if time.monotonic() - last_discovery >= REDISCOVER_S:
                book.discover(0.3)
                last_discovery = time.monotonic()
            if live is not None:
                live.update(render(book.rows(sort), sort, where), refresh=True)
            else:
                console.print(render(book.rows(sort), sort, where))
