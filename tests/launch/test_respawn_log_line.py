"""The supervisor's crash and respawn lines count restarts as "restart 2/3"."""

from __future__ import annotations

import logging
import subprocess
import sys
import time
from types import SimpleNamespace

import pytest

from agents_core.launch.supervisor import Supervisor


def _exited_process(code: int) -> subprocess.Popen[bytes]:
    proc = subprocess.Popen([sys.executable, "-c", f"raise SystemExit({code})"])
    proc.wait(10.0)
    return proc


def test_crash_and_respawn_lines_say_restart_n_of_max(caplog: pytest.LogCaptureFixture,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    supervisor = Supervisor([SimpleNamespace(component_name="arm")], max_retries=3, backoff_s=0.0)  # type: ignore[list-item]
    child = supervisor.children[0]
    spawned: list[str] = []
    monkeypatch.setattr(child, "spawn", lambda: spawned.append(child.name))
    child.restarts = 1
    child.proc = _exited_process(3)
    with caplog.at_level(logging.INFO, logger="agents_core.launch.supervisor"):
        supervisor._watch(child, time.monotonic(), False)
        supervisor._watch(child, time.monotonic() + 10.0, False)
    lines = [r.getMessage() for r in caplog.records]
    assert any("'arm'" in line and "exited with status 3; restart 2/3" in line for line in lines), lines
    assert any("respawning the process of 'arm' (restart 2/3)" in line for line in lines), lines
    assert spawned == ["arm"]


def test_the_give_up_line_counts_too(caplog: pytest.LogCaptureFixture) -> None:
    supervisor = Supervisor([SimpleNamespace(component_name="arm")], max_retries=3)  # type: ignore[list-item]
    child = supervisor.children[0]
    child.restarts = 3
    child.proc = _exited_process(1)
    with caplog.at_level(logging.INFO, logger="agents_core.launch.supervisor"):
        supervisor._watch(child, time.monotonic(), False)
    assert child.gave_up
    assert any("giving up on component 'arm' after 3 restart(s) (3/3)" in r.getMessage() for r in caplog.records)
