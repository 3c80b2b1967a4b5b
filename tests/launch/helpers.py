"""Running ``mp_recipe.py`` as a real launcher process and looking at its component processes."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from agents_core.testing.helpers import free_tcp_port

RECIPE = Path(__file__).with_name("mp_recipe.py")
REPO = Path(__file__).resolve().parents[2]
SECRET = "sk-test-7f3a9c-SECRET-KEY"


def direct_children(pid: int) -> list[int]:
    """The direct children of ``pid`` (from /proc)."""
    found: list[int] = []
    with contextlib.suppress(OSError):
        for task in os.listdir(f"/proc/{pid}/task"):
            with contextlib.suppress(OSError), open(f"/proc/{pid}/task/{task}/children") as f:
                found += [int(p) for p in f.read().split()]
    return sorted(set(found))


def is_fork_server(pid: int) -> bool:
    """True when ``pid`` is a launcher's fork server (agents_core.launch.fork_server)."""
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return b"agents_core.launch.fork_server" in f.read().split(b"\0")[:3]
    except OSError:
        return False


def child_pids(pid: int) -> list[int]:
    """The processes launcher ``pid`` started for its components: its direct children, where one is
    its fork server, that server's children in its place (a forked process keeps the server's argv,
    so it is told apart by its parent)."""
    found: list[int] = []
    for kid in direct_children(pid):
        found += direct_children(kid) if is_fork_server(kid) else [kid]
    return sorted(set(found))


def alive(pid: int) -> bool:
    """True while ``pid`` exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def shm_files() -> set[str]:
    return set(os.listdir("/dev/shm"))


def mapped_shm(pid: int) -> set[str]:
    names: set[str] = set()
    with contextlib.suppress(OSError), open(f"/proc/{pid}/maps") as maps:
        for line in maps:
            path = line.split(maxsplit=5)[-1].strip()
            if path.startswith("/dev/shm/"):
                names.add(path[len("/dev/shm/"):].removesuffix(" (deleted)"))
    return names


def leftover_segments(before: set[str]) -> set[str]:
    """Shared-memory files made since ``before`` that no live process maps: what a dead process left.

    Other tests on this machine create and use segments meanwhile; a segment in use (mapped or
    held open) is theirs.
    Zenoh's only: Fast DDS lock files (``*_el``) of other tests' ROS 2 runs are never mapped.
    """
    new = {f for f in shm_files() - before if f.endswith(".zenoh")}
    for entry in os.listdir("/proc"):
        if new and entry.isdigit():
            new -= mapped_shm(int(entry)) | open_shm(int(entry))
    return new


def open_shm(pid: int) -> set[str]:
    """The /dev/shm files process ``pid`` holds open (a segment may be open before it is mapped)."""
    names: set[str] = set()
    with contextlib.suppress(OSError):
        for fd in os.listdir(f"/proc/{pid}/fd"):
            with contextlib.suppress(OSError):
                target = os.readlink(f"/proc/{pid}/fd/{fd}")
                if target.startswith("/dev/shm/"):
                    names.add(target[len("/dev/shm/"):].removesuffix(" (deleted)"))
    return names


class RecipeRun:
    """A launcher process running mp_recipe.py; its stdout and stderr go to files."""

    def __init__(self, tmp: Path, transport: str = "zenoh", retries: int = 3,
                 extra: list[str] | None = None, env: dict[str, str] | None = None) -> None:
        self.port = free_tcp_port()
        self.out_path = tmp / "launcher.out"
        self.err_path = tmp / "launcher.err"
        self._out: IO[bytes] = self.out_path.open("wb")
        self._err: IO[bytes] = self.err_path.open("wb")
        argv = [sys.executable, str(RECIPE), "--transport", transport, "--port", str(self.port),
                "--retries", str(retries), "--api-key", "-", *(extra or [])]
        self.proc = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=self._out, stderr=self._err, cwd=REPO,
                                     env=env)
        assert self.proc.stdin is not None
        self.proc.stdin.write(SECRET.encode() + b"\n")
        self.proc.stdin.flush()

    @property
    def pid(self) -> int:
        return self.proc.pid

    def children(self) -> list[int]:
        return child_pids(self.pid)

    def output(self) -> str:
        if not self._out.closed:
            self._out.flush()
        return self.out_path.read_text(errors="replace")

    def log(self) -> str:
        if not self._err.closed:
            self._err.flush()
        return self.err_path.read_text(errors="replace")

    def wait_children(self, count: int, timeout: float = 30.0, exclude: set[int] | None = None) -> list[int]:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            pids = [p for p in self.children() if alive(p) and p not in (exclude or set())]
            if len(pids) >= count:
                return pids
            if self.proc.poll() is not None:
                raise AssertionError(f"the launcher exited with {self.proc.returncode}:\n{self.log()[-3000:]}")
            time.sleep(0.05)
        raise AssertionError(f"{count} component processes did not appear:\n{self.log()[-3000:]}")

    def stop(self) -> None:
        """SIGTERM, then SIGKILL; every process it started is killed by pid too."""
        kids = self.children()
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=20.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=5.0)
        for pid in kids:
            if alive(pid):
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
        if self.proc.stdin is not None:
            self.proc.stdin.close()
        self._out.close()
        self._err.close()


@contextlib.contextmanager
def recipe_run(tmp: Path, **kwargs: Any) -> Iterator[RecipeRun]:
    run = RecipeRun(tmp, **kwargs)
    try:
        yield run
    finally:
        run.stop()


def wait_for(predicate: Any, timeout: float, what: str, step: float = 0.02) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(step)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def parent_pid(pid: int) -> int:
    """The parent of process ``pid``, from /proc (field 4 of its stat line)."""
    with open(f"/proc/{pid}/stat") as f:
        return int(f.read().rsplit(")", 1)[1].split()[1])


def ask_where(launcher: Any, prefix: str, timeout: float = 20.0) -> list[int]:
    """Ask a ``forked_components`` component on ``<prefix>/in``: [pid that imported its module, its own pid]."""
    from agents_core import Topic  # noqa: PLC0415 - the helpers above need no agents_core

    got: list[str] = []
    sub = launcher.transport.create_subscription(Topic(f"{prefix}/out", "String"), got.append)
    pub = launcher.transport.create_publisher(Topic(f"{prefix}/in", "String"))
    try:
        wait_for(lambda: pub.publish("hi") or got, timeout=timeout, what=f"an answer on {prefix}/out", step=0.2)
    finally:
        sub.close()
    return [int(part) for part in got[0].split(":")[1:]]


def kill_and_wait_for_respawn(launcher: Any, timeout: float) -> Any:
    """SIGKILL the first component process; return its supervisor child once its new process is active."""
    supervisor = launcher.supervisor
    assert supervisor is not None
    child = supervisor.children[0]
    old = child.pid
    assert old is not None
    os.kill(old, signal.SIGKILL)
    wait_for(lambda: child.pid != old and child.state == "active", timeout=timeout, what="the respawn")
    assert child.crashes == 1 and child.restarts == 1
    return child
