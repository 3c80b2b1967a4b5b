"""Item 8 of issue 38 (two recipes on one host): the second recipe on the loopback rendezvous says at start that
it joined the peers already there, and ``AGENTS_ZENOH_PORT`` gives a recipe a rendezvous of its own (the two
then do not see each other). The rendezvous port is a free one, so parallel runs never meet."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from agents_core.testing.helpers import free_tcp_port

pytestmark = pytest.mark.zenoh

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _talker(port: int, log: Path) -> subprocess.Popen[bytes]:
    inherited = ("AGENTS_ZENOH_", "AGENTS_TRANSPORT", "AGENTS_QUIET")
    env = {k: v for k, v in os.environ.items() if not k.startswith(inherited)}
    with log.open("wb") as out:
        return subprocess.Popen([sys.executable, str(EXAMPLES / "talker.py"), "--transport", "zenoh", "--seconds",
                                 "60"], cwd=EXAMPLES, stdout=out, stderr=subprocess.STDOUT,
                                env={**env, "AGENTS_ZENOH_PORT": str(port), "PYTHONUNBUFFERED": "1"})


def _stop(process: subprocess.Popen[bytes]) -> None:
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout=20)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(timeout=10)


def _wait_ready(log: Path) -> str:
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        text = log.read_text(errors="replace")
        if "READY" in text:
            return text
        time.sleep(0.2)
    raise AssertionError(f"not ready: {log.read_text(errors='replace')[-2000:]}")


def test_the_second_recipe_says_it_joined_and_a_port_of_its_own_keeps_it_apart(tmp_path: Path) -> None:
    pytest.importorskip("zenoh")
    shared, other = free_tcp_port(), free_tcp_port()
    first = _talker(shared, tmp_path / "first.log")
    second = third = None
    try:
        first_text = _wait_ready(tmp_path / "first.log")
        second = _talker(shared, tmp_path / "second.log")
        second_text = _wait_ready(tmp_path / "second.log")
        third = _talker(other, tmp_path / "third.log")
        third_text = _wait_ready(tmp_path / "third.log")
    finally:
        for process in (third, second, first):
            if process is not None:
                _stop(process)
    assert f"loopback rendezvous tcp/127.0.0.1:{shared}" in first_text
    assert "joined the peers already there" not in first_text
    assert "joined the peers already there: another recipe on this host shares its topics" in second_text, second_text
    assert f"tcp/127.0.0.1:{other}" in third_text and "joined the peers" not in third_text
