"""Repeated Ctrl-C during a long step, in a subprocess, on Zenoh and ROS 2 (issue 12).

The recipe (``tests/launch/signal_recipe.py``) runs one component whose step takes a minute and whose
``step_finish_timeout`` is a minute too, so the first SIGINT alone would wait that long:

- two SIGINTs: the second makes the shutdown hurry; the process closes its transport and exits
  cleanly (status 0) within seconds, leaving no process and no new shared-memory segment;
- three SIGINTs while the deactivate itself hangs: the third exits at once with status 130.

Each subprocess is killed by PID in a ``finally``; every wait is bounded.
"""

from __future__ import annotations

import importlib.util
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.conftest import free_tcp_port

REPO = Path(__file__).resolve().parents[2]


def _has(module: str) -> bool:
    return importlib.util.find_spec(module) is not None


TRANSPORTS = [
    pytest.param("zenoh", marks=[pytest.mark.zenoh,
                                 pytest.mark.skipif(not _has("zenoh"), reason="needs the zenoh extra")]),
    pytest.param("ros2", marks=[pytest.mark.ros2,
                                pytest.mark.skipif(not _has("rclpy"), reason="needs the ros2 extra")]),
]


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ROS_DOMAIN_ID"] = str(1 + (os.getpid() + 70) % 100)
    env["PYTHONUNBUFFERED"] = "1"
    return env


def _mapped_elsewhere(path: str) -> bool:
    """Whether a live process still maps ``path`` (Fast DDS shares its port segments between participants)."""
    for maps in Path("/proc").glob("[0-9]*/maps"):
        try:
            if path in maps.read_text():
                return True
        except OSError:
            continue
    return False


class _Recipe:
    def __init__(self, transport: str, *extra: str) -> None:
        args = [sys.executable, "-m", "tests.launch.signal_recipe", transport]
        if transport == "zenoh":
            args.append(f"tcp/127.0.0.1:{free_tcp_port()}")
        self.proc = subprocess.Popen([*args, *extra], cwd=REPO, env=_env(), stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True)
        self.lines: list[str] = []

    def wait_for_line(self, text: str, timeout: float = 60.0) -> None:
        assert self.proc.stdout is not None
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            line = self.proc.stdout.readline()
            if not line:
                break
            self.lines.append(line)
            if text in line:
                return
        raise AssertionError(f"the recipe never printed {text!r}; output:\n{''.join(self.lines)}")

    def output(self) -> str:
        assert self.proc.stdout is not None
        return "".join(self.lines) + self.proc.stdout.read()

    def shm_segments(self) -> set[str]:
        """The /dev/shm files this process has mapped now."""
        try:
            maps = Path(f"/proc/{self.proc.pid}/maps").read_text()
        except OSError:
            return set()
        paths = {parts[5].strip() for parts in (line.split(None, 5) for line in maps.splitlines())
                 if len(parts) == 6 and parts[5].startswith("/dev/shm/")}
        # LTTng's wait files (mapped by the ROS 2 tracing library) are shared by every process
        # of the machine and live on purpose; they are not the middleware's segments. Fast DDS's
        # port mailboxes (fastrtps_port<N>) are shared by every participant of the machine that uses
        # that port (other ROS 2 tests' processes too), so whether one outlives this process is Fast
        # DDS's machine-wide business (CI saw one stay); its own segments (fastrtps_<guid>) count.
        return {p for p in paths if not p.startswith(("/dev/shm/lttng-ust-wait", "/dev/shm/fastrtps_port"))}

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)
        if self.proc.stdout is not None:
            self.proc.stdout.close()


@pytest.fixture
def recipes() -> Iterator[list[_Recipe]]:
    started: list[_Recipe] = []
    yield started
    for recipe in started:
        recipe.kill()


@pytest.mark.slow
@pytest.mark.parametrize("transport", TRANSPORTS)
def test_a_second_sigint_hurries_the_shutdown_and_the_transport_is_closed(
        transport: str, recipes: list[_Recipe]) -> None:
    recipe = _Recipe(transport)
    recipes.append(recipe)
    recipe.wait_for_line("STEP STARTED")
    mapped = recipe.shm_segments()
    recipe.proc.send_signal(signal.SIGINT)
    time.sleep(0.5)
    assert recipe.proc.poll() is None, "the first signal alone waits for the running step"
    start = time.monotonic()
    recipe.proc.send_signal(signal.SIGINT)
    try:
        code = recipe.proc.wait(20.0)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the process hung after a second SIGINT; output:\n{''.join(recipe.lines)}")
    took = time.monotonic() - start
    output = recipe.output()
    assert code == 0, output
    assert "CLEAN EXIT" in output
    assert "Traceback" not in output, output
    assert took < 15.0, f"exit took {took:.1f} s after the second signal"
    # The process is gone, and so are the shared-memory segments it had mapped.
    assert not Path(f"/proc/{recipe.proc.pid}").exists()
    left = sorted(path for path in mapped if Path(path).exists() and not _mapped_elsewhere(path))
    assert not left, f"shared-memory segments left behind: {left}"


@pytest.mark.slow
@pytest.mark.parametrize("transport", TRANSPORTS)
def test_a_third_sigint_exits_at_once(transport: str, recipes: list[_Recipe]) -> None:
    recipe = _Recipe(transport, "--stuck-deactivate")
    recipes.append(recipe)
    recipe.wait_for_line("STEP STARTED")
    recipe.proc.send_signal(signal.SIGINT)
    recipe.wait_for_line("DEACTIVATE STUCK", timeout=20.0)
    recipe.proc.send_signal(signal.SIGINT)
    time.sleep(0.5)
    assert recipe.proc.poll() is None, "a hanging deactivate is not cut short by the second signal"
    start = time.monotonic()
    recipe.proc.send_signal(signal.SIGINT)
    code = recipe.proc.wait(10.0)
    assert code == 128 + signal.SIGINT
    assert time.monotonic() - start < 5.0
