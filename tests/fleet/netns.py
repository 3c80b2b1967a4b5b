"""Network hosts made of Linux network namespaces, for the fleet test: one switch, N hosts, real IP links.

:class:`Lan` creates a *switch* namespace holding a bridge and one namespace per host, each joined
to the bridge by a veth pair (created straight inside the namespaces: nothing is added to the
machine's own network), with the addresses the test gives (``10.77.0.0/24`` by default: the
namespaces are private, so the block never meets the machine's own). Each host has only its
veth and its loopback: a process started in it (:meth:`Lan.start`) reaches the others through
the bridge, on their addresses, and nothing else.

Everything is named after this process (``agfl<pid>_<host>``), and :meth:`Lan.close` removes it
all even after a failure: the processes started here (by PID, their process groups), any other
process still inside a namespace (``ip netns pids``, by PID), then the namespaces (their veths
go with them). :func:`netns_unavailable` says why the machine cannot do it (not root, no ``ip``,
namespaces refused), for the skip.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import time
from collections.abc import Iterator, Sequence
from pathlib import Path

__all__ = ["Lan", "kill", "netns_unavailable", "stop"]

_IP = shutil.which("ip") or "/usr/sbin/ip"


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    return subprocess.run([_IP, *args], capture_output=True, text=True, timeout=20, check=check)


def netns_unavailable() -> str | None:
    """Why network namespaces cannot be made here, or None."""
    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        return "creating network namespaces needs root (run `nox -s fleet` as root, or in CI)"
    if not Path(_IP).is_file():
        return "no `ip` command (iproute2) on this machine"
    probe = f"agfl{os.getpid()}_probe"
    try:
        done = _ip("netns", "add", probe, check=False)
        if done.returncode != 0:
            return f"`ip netns add` is refused here: {done.stderr.strip()}"
        link = _ip("-n", probe, "link", "add", "p0", "type", "veth", "peer", "name", "p1", check=False)
        if link.returncode != 0:
            return f"veth pairs cannot be created here: {link.stderr.strip()}"
    finally:
        _ip("netns", "del", probe, check=False)
    return None


class Lan:
    """A switch and hosts on it (see the module docstring); a context manager that always cleans up."""

    def __init__(self, hosts: Sequence[str], subnet: str = "10.77.0") -> None:
        self.prefix = f"agfl{os.getpid()}"
        self.switch = f"{self.prefix}_sw"
        self.address = {host: f"{subnet}.{i}" for i, host in enumerate(hosts, start=1)}
        self._made: list[str] = []
        self._processes: list[subprocess.Popen[bytes]] = []

    def ns(self, host: str) -> str:
        """The namespace of ``host``."""
        return f"{self.prefix}_{host}"

    def __enter__(self) -> Lan:
        try:
            self._add(self.switch)
            _ip("-n", self.switch, "link", "add", "br0", "type", "bridge")
            _ip("-n", self.switch, "link", "set", "br0", "up")
            for i, (host, address) in enumerate(self.address.items()):
                ns = self.ns(host)
                self._add(ns)
                _ip("-n", ns, "link", "set", "lo", "up")
                _ip("-n", ns, "link", "add", "eth0", "type", "veth", "peer", "name", f"port{i}", "netns", self.switch)
                _ip("-n", ns, "addr", "add", f"{address}/24", "dev", "eth0")
                _ip("-n", ns, "link", "set", "eth0", "up")
                _ip("-n", self.switch, "link", "set", f"port{i}", "master", "br0")
                _ip("-n", self.switch, "link", "set", f"port{i}", "up")
        except BaseException:
            self.close()
            raise
        return self

    def _add(self, ns: str) -> None:
        _ip("netns", "del", ns, check=False)  # a leftover of a crashed run with this PID
        _ip("netns", "add", ns)
        self._made.append(ns)

    def run(self, host: str, argv: Sequence[str], timeout: float = 60.0,
            env: dict[str, str] | None = None, cwd: str | Path | None = None) -> subprocess.CompletedProcess[str]:
        """Run ``argv`` inside ``host`` to completion (bounded)."""
        return subprocess.run([_IP, "netns", "exec", self.ns(host), *argv], capture_output=True, text=True,
                              timeout=timeout, check=False, env=env, cwd=cwd)

    def start(self, host: str, argv: Sequence[str], log: Path, env: dict[str, str] | None = None,
              cwd: str | Path | None = None) -> subprocess.Popen[bytes]:
        """Start ``argv`` inside ``host`` in a process group of its own (``ip netns exec`` execs it: same PID)."""
        with log.open("wb") as out:
            process = subprocess.Popen([_IP, "netns", "exec", self.ns(host), *argv], stdout=out,
                                       stderr=subprocess.STDOUT, env=env, cwd=cwd, start_new_session=True)
        self._processes.append(process)
        return process

    def close(self) -> None:
        """Stop every process (SIGINT, then SIGKILL by PID), then delete every namespace made; idempotent."""
        for process in self._processes:
            stop(process)
        for ns in self._made:
            for pid in self._pids_in(ns):
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
        for ns in reversed(self._made):
            _ip("netns", "del", ns, check=False)
        self._made.clear()

    @staticmethod
    def _pids_in(ns: str) -> Iterator[int]:
        done = _ip("netns", "pids", ns, check=False)
        for word in done.stdout.split():
            if word.isdigit() and int(word) != os.getpid():
                yield int(word)

    def __exit__(self, *exc: object) -> None:
        self.close()

    def names(self) -> list[str]:
        """The namespaces that exist now with this LAN's prefix (for the test's cleanup check)."""
        listed = _ip("netns", "list", check=False).stdout.split()
        return [n for n in listed if n.startswith(self.prefix + "_")]


def stop(process: subprocess.Popen[bytes], timeout: float = 10.0) -> None:
    """SIGINT to its process group, SIGKILL after ``timeout``; always reaped."""
    if process.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGINT)
        try:
            process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(process.pid, signal.SIGKILL)
            process.wait(timeout=10.0)


def kill(process: subprocess.Popen[bytes]) -> float:
    """SIGKILL the process group at once (a crash); the time it happened (``time.time()``)."""
    when = time.time()
    with contextlib.suppress(ProcessLookupError):
        os.killpg(process.pid, signal.SIGKILL)
    process.wait(timeout=10.0)
    return when
