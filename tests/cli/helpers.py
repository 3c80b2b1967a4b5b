"""Starting the CLI and recipes in subprocesses for the end-to-end tests, and stopping them by PID."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[2]
RECIPE = "tests/cli/cli_recipe.py"
#: The ROS domain of this engineer's CLI tests (see the project notes); LOCALHOST discovery only.
ROS_ENV = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_DOMAIN_ID": os.environ.get("ROS_DOMAIN_ID", "64")}


def cli_env(**extra: str) -> dict[str, str]:
    """The environment of a CLI or recipe subprocess: no inherited transport settings, ROS kept local."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("AGENTS_ZENOH_", "AGENTS_TRANSPORT"))}
    env.update(ROS_ENV)
    env.update(extra)
    return env


def cli(*args: str, timeout: float = 60.0, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """Run ``python -m agents_core.cli ARGS`` to completion (bounded)."""
    return subprocess.run([sys.executable, "-m", "agents_core.cli", *args], cwd=REPO, env=env or cli_env(),
                          capture_output=True, text=True, timeout=timeout, check=False)


def cli_json(*args: str, timeout: float = 60.0) -> Any:
    """Run a CLI command with ``--json`` and parse its (single-document) output; fails loudly otherwise."""
    done = cli(*args, "--json", timeout=timeout)
    assert done.returncode == 0, f"{args}: rc={done.returncode} stderr={done.stderr[-2000:]}"
    return json.loads(done.stdout)


def start(*args: str, env: dict[str, str], log: Path) -> subprocess.Popen[bytes]:
    """Start ``python -m agents_core.cli ARGS`` (a recipe, a router) in its own process group."""
    with log.open("wb") as out:
        return subprocess.Popen([sys.executable, "-m", "agents_core.cli", *args], cwd=REPO, env=env,
                                stdout=out, stderr=subprocess.STDOUT, start_new_session=True)


def stop(process: subprocess.Popen[bytes], timeout: float = 15.0) -> None:
    """SIGINT, then SIGKILL after ``timeout``: by PID (its own process group), always reaped."""
    if process.poll() is None:
        os.killpg(process.pid, signal.SIGINT)
        try:
            process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait(timeout=10.0)


def wait_until(predicate: Any, timeout: float, interval: float = 0.5) -> bool:
    """Poll ``predicate`` until true or ``timeout`` s passed."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return bool(predicate())


def listening_tcp_ports(pid: int) -> set[int]:
    """The TCP ports process ``pid`` listens on (from /proc: its socket inodes in the LISTEN state)."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    ports = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            fields = line.split()
            if fields[3] == "0A" and fields[9] in inodes:  # 0A: LISTEN
                ports.add(int(fields[1].rsplit(":", 1)[1], 16))
    return ports
