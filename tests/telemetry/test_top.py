"""``agentsctl top`` in a real terminal (a pty) against a two-process recipe on Zenoh.

The table shows a row for each component, its figures change from one refresh to the next, a
sort key re-sorts it, and ``q`` quits (exit status 0). ``--json`` prints the rows once.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import pty
import re
import select
import struct
import subprocess
import sys
import termios
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("zenoh")

from agents_core.testing.recipes import RecipeProcess, open_recipe_transport, recipe_environment

pytestmark = pytest.mark.zenoh

REPO = Path(__file__).resolve().parents[2]
_ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")


@contextlib.contextmanager
def _recipe(tmp_path: Path) -> Iterator[str]:
    """The recipe running; the endpoint to connect to."""
    rt = open_recipe_transport("zenoh")
    assert rt.endpoint is not None
    process = RecipeProcess("tests.telemetry.top_recipe", rt.recipe_args, tmp_path / "recipe.log", cwd=REPO,
                            env=recipe_environment())
    try:
        process.wait_ready(90)
        yield rt.endpoint
    finally:
        rt.close()
        process.stop()


def _top_command(endpoint: str, *extra: str) -> list[str]:
    return [sys.executable, "-m", "agents_core.cli", "top", "--transport", "zenoh", "--connect", endpoint, *extra]


def _read_until(fd: int, predicate: object, timeout: float, buffer: list[str]) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        ready, _, _ = select.select([fd], [], [], 0.1)
        if ready:
            try:
                chunk = os.read(fd, 65536)
            except OSError:  # the child closed its end
                return bool(predicate(_ANSI.sub("", "".join(buffer))))  # type: ignore[operator]
            buffer.append(chunk.decode("utf-8", "replace"))
        if predicate(_ANSI.sub("", "".join(buffer))):  # type: ignore[operator]
            return True
    return False


def _row(text: str, name: str) -> list[str]:
    """The cells of the last rendered row of component ``name``."""
    lines = [line for line in text.splitlines() if re.search(rf"[│|]\s*{name}\s*[│|]", line)]
    return [cell.strip() for cell in re.split(r"[│|]", lines[-1]) if cell.strip()] if lines else []


def test_top_in_a_terminal(tmp_path: Path) -> None:
    with _recipe(tmp_path) as endpoint:
        master, slave = pty.openpty()
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 160, 0, 0))
        env = {**recipe_environment(), "COLUMNS": "160", "LINES": "40", "TERM": "xterm-256color"}
        proc = subprocess.Popen(_top_command(endpoint, "--interval", "0.5"), stdin=slave, stdout=slave, stderr=slave,
                                env=env, cwd=REPO, start_new_session=True)
        os.close(slave)
        out: list[str] = []
        try:
            both = _read_until(master, lambda t: _row(t, "ticker")[1:2] == ["active"] and len(_row(t, "ticker")) > 5
                               and _row(t, "echo")[1:2] == ["active"], 30, out)
            assert both, f"no rows for both components:\n{_ANSI.sub('', ''.join(out))[-3000:]}"
            first = _row(_ANSI.sub("", "".join(out)), "ticker")
            assert first[1] == "active"
            # The figures move: the ticker's row changes between refreshes (steps/s, times, CPU).
            changed = _read_until(master, lambda t: _row(t, "ticker") != first, 10, out)
            assert changed, f"the ticker's row never changed: {first}"
            rate = float(_row(_ANSI.sub("", "".join(out)), "ticker")[3])
            assert 10.0 <= rate <= 30.0, rate  # 20 Hz
            os.write(master, b"r")  # sort by rate
            assert _read_until(master, lambda t: "sorted by rate_hz" in t, 5, out)
            os.write(master, b"q")
            # Read on while it stops: a terminal whose output is not read blocks the writer.
            _read_until(master, lambda _: proc.poll() is not None, 10, out)
            assert proc.wait(timeout=5) == 0
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait(timeout=5)
            os.close(master)


def test_top_json_prints_once(tmp_path: Path) -> None:
    with _recipe(tmp_path) as endpoint:
        time.sleep(1.5)  # a status with a step rate (computed over at least 0.5 s)
        done = subprocess.run(_top_command(endpoint, "--json"), capture_output=True, text=True, timeout=60, check=False,
                              cwd=REPO, env=recipe_environment())
        assert done.returncode == 0, done.stderr
        rows = {row["component"]: row for row in json.loads(done.stdout)}
        assert set(rows) >= {"ticker", "echo"}
        for name in ("ticker", "echo"):
            row = rows[name]
            assert row["state"] == "active" and row["health"] == "HEALTHY"
            assert row["steps"] > 0 and row["pid"] > 0 and row["rss_mb"] > 0
            assert "p99_ms" in row and "drops" in row and "restarts" in row
        assert rows["ticker"]["pid"] != rows["echo"]["pid"]
