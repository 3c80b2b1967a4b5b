"""Item 8 of issue 38: ``agentsctl topics pub`` warns when nothing subscribes to the topic, or when its
subscribers expect another type (it used to say "published" either way). The talker example runs on a
private Zenoh rendezvous (``AGENTS_ZENOH_PORT``); its listener subscribes to ``chatter`` (String)."""

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


def _env(port: int) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("AGENTS_ZENOH_", "AGENTS_TRANSPORT"))}
    return {**env, "AGENTS_ZENOH_PORT": str(port)}


def _pub(port: int, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "agents_core.cli", "topics", "pub", *args, "--wait", "3"],
                          env=_env(port), capture_output=True, text=True, timeout=90, check=False)


def test_pub_warns_without_a_subscriber_and_on_the_wrong_type(tmp_path: Path) -> None:
    pytest.importorskip("zenoh")
    pytest.importorskip("typer")
    port = free_tcp_port()
    lonely = _pub(port, "nobody_listens", "String", "hello")
    assert lonely.returncode == 0, lonely.stderr
    assert "warning: no subscriber of 'nobody_listens' appeared within 3 s" in lonely.stderr
    log = (tmp_path / "talker.log").open("wb")
    talker = subprocess.Popen([sys.executable, str(EXAMPLES / "talker.py"), "--transport", "zenoh", "--seconds", "90"],
                              cwd=EXAMPLES, stdout=log, stderr=subprocess.STDOUT, env=_env(port))
    try:
        deadline = time.monotonic() + 60
        right = _pub(port, "chatter", "String", "hi")
        while "no subscriber" in right.stderr and time.monotonic() < deadline:
            right = _pub(port, "chatter", "String", "hi")
        assert right.returncode == 0 and "warning" not in right.stderr, right.stderr
        wrong = _pub(port, "chatter", "Int32", "5")
        assert "warning: 'chatter' carries String (its subscribers expect it), not Int32" in wrong.stderr, wrong.stderr
    finally:
        talker.terminate()
        try:
            talker.wait(timeout=20)
        except subprocess.TimeoutExpired:
            talker.kill()
            talker.wait(timeout=10)
        log.close()
