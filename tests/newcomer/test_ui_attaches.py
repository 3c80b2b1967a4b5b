"""Item 3 of issue 38: ``agentsctl ui`` without ``--connect`` attaches to the recipe on this host, as every other
``agentsctl`` command does (not an isolated, empty session: "UI for []").

The talker example runs on Zenoh in its own process and neither command line names an endpoint. What a user
does is the loopback rendezvous (nothing set: both meet on its port); here that port is a free one given to
both with ``AGENTS_ZENOH_PORT``, so that parallel runs never meet. The same through ``AGENTS_ZENOH_LISTEN`` /
``AGENTS_ZENOH_CONNECT`` (what the other commands honour too)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

from agents_core.testing.helpers import free_tcp_port

pytestmark = pytest.mark.zenoh

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = REPO / "examples"


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("AGENTS_ZENOH_", "AGENTS_TRANSPORT"))}
    return {**env, "PYTHONUNBUFFERED": "1", **extra}


@pytest.mark.parametrize("meeting", ["rendezvous", "endpoint"])
def test_agentsctl_ui_without_connect_shows_the_recipe(tmp_path: Path, meeting: str) -> None:
    pytest.importorskip("zenoh")
    pytest.importorskip("starlette", reason="the ui extra is not installed")
    free = free_tcp_port()
    endpoint = f"tcp/127.0.0.1:{free}"
    if meeting == "rendezvous":
        recipe_env, client_env = _env(AGENTS_ZENOH_PORT=str(free)), _env(AGENTS_ZENOH_PORT=str(free))
    else:
        recipe_env, client_env = _env(AGENTS_ZENOH_LISTEN=endpoint), _env(AGENTS_ZENOH_CONNECT=endpoint)
    log = (tmp_path / "talker.log").open("wb")
    talker = subprocess.Popen([sys.executable, str(EXAMPLES / "talker.py"), "--transport", "zenoh", "--seconds",
                               "120"], cwd=EXAMPLES, stdout=log, stderr=subprocess.STDOUT, env=recipe_env)
    port = free_tcp_port()
    ui = None
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:  # the talker is up once the other commands see it
            listed = subprocess.run([sys.executable, "-m", "agents_core.cli", "components", "list", "--json"],
                                    env=client_env, capture_output=True, text=True, timeout=60, check=False)
            if listed.returncode == 0 and "talker" in listed.stdout:
                break
            time.sleep(1.0)
        assert "talker" in listed.stdout, listed.stderr
        ui = subprocess.Popen([sys.executable, "-m", "agents_core.cli", "ui", "--port", str(port), "--seconds", "60"],
                              env=client_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        assert ui.stdout is not None
        first = ui.stdout.readline()
        assert "UI for ['listener', 'talker']" in first, (first, ui.stderr.read() if ui.poll() is not None else "")
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/api/interfaces", timeout=10) as reply:
            shown = json.loads(reply.read())
        names = sorted(c["name"] for c in shown["components"])
        assert names == ["listener", "talker"]
    finally:
        for process in (ui, talker):
            if process is not None and process.poll() is None:
                process.terminate()
                try:
                    process.communicate(timeout=20)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.communicate(timeout=10)
            elif process is not None:
                process.communicate(timeout=10)
        log.close()
