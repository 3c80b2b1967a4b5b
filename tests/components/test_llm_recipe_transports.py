"""The same LLM recipe file (llm_recipe.py) answers on memory, zenoh and ros2.

Memory runs in this process; zenoh and ros2 run the recipe in a child process (killed by PID
afterwards) and ask from this one through the framework's own transport. Transports whose extra
is missing are skipped with the reason.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from agents_core import Launcher
from agents_core.messages import StreamingStringMsg
from agents_core.transport.contract import Transport

from ..conftest import free_tcp_port, wait_for
from . import llm_recipe
from .models_dir import REPO, needs_smollm2

pytestmark = pytest.mark.local_models


def _ask(transport: Transport, question: str, attempts: int = 4) -> list[StreamingStringMsg]:
    chunks: list[StreamingStringMsg] = []
    done = threading.Event()

    def on_chunk(msg: StreamingStringMsg) -> None:
        chunks.append(msg)
        if msg.done:
            done.set()

    sub = transport.create_subscription(llm_recipe.ANSWER, on_chunk)
    pub = transport.create_publisher(llm_recipe.QUESTION)
    try:
        # Across processes the first sample can precede discovery; ask again, a bounded number of times.
        for _ in range(attempts):
            pub.publish(question)
            if wait_for(lambda: bool(chunks), timeout=10):
                break
        assert done.wait(60), f"no complete answer; got {len(chunks)} chunks"
    finally:
        pub.close()
        sub.close()
    return chunks


def _check(chunks: list[StreamingStringMsg]) -> None:
    first_answer: list[StreamingStringMsg] = []
    for c in chunks:
        first_answer.append(c)
        if c.done:
            break
    text = "".join(c.data for c in first_answer)
    assert len(first_answer) >= 3 and text.strip(), text


def test_recipe_on_memory() -> None:
    needs_smollm2()
    launcher = Launcher("memory")
    launcher.add_pkg(components=[llm_recipe.build()])
    with launcher:
        _check(_ask(launcher.transport, "What is the capital of France?"))


class _RecipeProcess:
    def __init__(self, args: list[str], env: dict[str, str], log: Path) -> None:
        self.log_path = log
        self._log = log.open("w")
        self.proc = subprocess.Popen([sys.executable, "-m", "tests.components.llm_recipe", *args], cwd=REPO,
                                     env=env, stdout=subprocess.PIPE, stderr=self._log, text=True)

    def wait_ready(self, timeout: float = 60) -> None:
        assert self.proc.stdout is not None
        ready: list[str] = []
        reader = threading.Thread(target=lambda: ready.append(self.proc.stdout.readline()), daemon=True)  # type: ignore[union-attr]
        reader.start()
        reader.join(timeout)
        if not ready or ready[0].strip() != "READY":
            self.stop()
            pytest.fail(f"recipe did not start: {self.log_path.read_text()[-2000:]}")

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=10)
        if self.proc.stdout is not None:
            self.proc.stdout.close()
        self._log.close()


def _recipe(args: list[str], env: dict[str, str], tmp_path: Path) -> Iterator[_RecipeProcess]:
    recipe = _RecipeProcess(args, env, tmp_path / "recipe.log")
    try:
        recipe.wait_ready()
        yield recipe
    finally:
        recipe.stop()


def test_recipe_on_zenoh(tmp_path: Path) -> None:
    needs_smollm2()
    if importlib.util.find_spec("zenoh") is None:
        pytest.skip("zenoh transport not available here: the zenoh extra is not installed")
    # Imported here: they exist only where the zenoh extra is installed.
    from agents_zenoh.transport import ZenohTransport  # noqa: PLC0415

    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    for _recipe_proc in _recipe(["--transport", "zenoh", "--listen", endpoint], env, tmp_path):
        asker = ZenohTransport(mode="peer", listen=[], connect=[endpoint], multicast_scouting=False)
        try:
            _check(_ask(asker, "What is the capital of France?"))
        finally:
            asker.close()


@pytest.mark.ros2
def test_recipe_on_ros2(tmp_path: Path) -> None:
    needs_smollm2()
    if importlib.util.find_spec("rclpy") is None:
        pytest.skip("ros2 transport not available here: the ros2 extra (rclpy) is not installed")
    # Imported here: they exist only where the ros2 extra is installed.
    from agents_ros2.transport import Ros2Transport  # noqa: PLC0415

    from ..conformance.ros2_pair import private_ros_environment  # noqa: PLC0415

    domain_id = private_ros_environment()
    env: dict[str, Any] = dict(os.environ, PYTHONUNBUFFERED="1")
    for _recipe_proc in _recipe(["--transport", "ros2"], env, tmp_path):
        asker = Ros2Transport(domain_id=domain_id)
        try:
            _check(_ask(asker, "What is the capital of France?"))
        finally:
            asker.close()
