"""Attacks on the fork server (:mod:`agents_core.launch.fork_server`) and its forked processes.

The server is driven here directly, over a socket pair of this test's own, as the launcher
drives it: who else can reach it (nobody: no path, no abstract name), what hostile packets do
(ignored or refused; the server keeps serving), which descriptors a forked process holds (no
server socket; nothing it would pass on to a program it runs), and what a SIGKILL of the server
does to a forked process (it ends too).
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from agents_core.launch.fork_server import fork_available

from ..launch.helpers import REPO, alive, wait_for

pytestmark = pytest.mark.skipif(not fork_available(), reason="the fork server needs Linux")

_O_CLOEXEC = 0o2000000


class Server:
    """A fork server started as the launcher starts it, with this test holding the other end."""

    def __init__(self) -> None:
        self.sock, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        env = {**os.environ, "PYTHONPATH": f"{REPO / 'src'}:{REPO}"}
        self.proc = subprocess.Popen([sys.executable, "-m", "agents_core.launch.fork_server", "--socket-fd",
                                      str(theirs.fileno())], pass_fds=(theirs.fileno(),), env=env,
                                     stdin=subprocess.DEVNULL)
        theirs.close()
        self.sock.settimeout(20.0)
        self.children: list[int] = []

    def send(self, data: bytes, fds: list[int] | None = None) -> None:
        socket.send_fds(self.sock, [data], fds or [])

    def reply(self, request_id: int) -> dict[str, Any]:
        """The reply to request ``request_id`` (exit notices and other replies are skipped)."""
        for _ in range(50):
            message = json.loads(self.sock.recv(1 << 20))
            if message.get("id") == request_id:
                return dict(message)
        raise AssertionError("no reply")

    def fork(self, request_id: int) -> tuple[int, int, int]:
        """A forked child, the write end of its stdin, the read end of its reports."""
        stdin_read, stdin_write = os.pipe()
        report_read, report_write = os.pipe()
        self.send(json.dumps({"op": "fork", "id": request_id, "name": "probe"}).encode(), [stdin_read, report_write])
        os.close(stdin_read)
        os.close(report_write)
        answer = self.reply(request_id)
        assert answer.get("id") == request_id and "pid" in answer, answer
        self.children.append(int(answer["pid"]))
        return int(answer["pid"]), stdin_write, report_read

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.sock.close()
        for pid in [*self.children, self.proc.pid]:
            if alive(pid):
                os.kill(pid, signal.SIGKILL)
        self.proc.wait(timeout=10)


@pytest.fixture
def server() -> Iterator[Server]:
    started = Server()
    try:
        yield started
    finally:
        started.close()


def _unix_paths() -> dict[int, str]:
    """inode -> bound name of every Unix socket in this network namespace (empty: unnamed)."""
    names: dict[int, str] = {}
    for line in Path("/proc/net/unix").read_text().splitlines()[1:]:
        parts = line.split()
        names[int(parts[6])] = parts[7] if len(parts) > 7 else ""
    return names


def _sockets(pid: int) -> list[int]:
    found = []
    for fd in os.listdir(f"/proc/{pid}/fd"):
        with contextlib.suppress(OSError):
            target = os.readlink(f"/proc/{pid}/fd/{fd}")
            if target.startswith("socket:["):
                found.append(int(target[8:-1]))
    return found


def test_nobody_else_can_connect_to_the_server(server: Server) -> None:
    _, stdin_write, report_read = server.fork(1)  # the server is up and serving
    names = _unix_paths()
    inodes = _sockets(server.proc.pid)
    assert inodes, "the server holds its socket"
    for inode in inodes:  # no path and no abstract (@) name: only the holder of the pair's other end
        assert names.get(inode, "") == "", (inode, names.get(inode))
    os.close(stdin_write)
    os.close(report_read)


def test_hostile_packets_are_ignored_or_refused_and_the_server_keeps_serving(server: Server) -> None:
    junk = [b"{not json", b"\xff\xfe", b"[]", b"42", b'"fork"', b"null", b'{"op": "fork"}',
            b'{"op": "fork", "id": {"a": 1}}', b'{"op": "preload", "modules": 5, "path": 7}',
            b"x" * 200_000]  # about the most one packet carries
    for data in junk:
        server.send(data)
    # a fork request with one descriptor, and one with three (the third is dropped by the kernel)
    one_r, one_w = os.pipe()
    server.send(json.dumps({"op": "fork", "id": 7}).encode(), [one_r])
    assert "error" in server.reply(7)
    fds = [os.pipe() for _ in range(2)]
    server.send(json.dumps({"op": "fork", "id": 8}).encode(), [fds[0][0], fds[1][1], one_w])
    for read_fd, write_fd in fds:
        os.close(read_fd)
        os.close(write_fd)
    for fd in (one_r, one_w):
        os.close(fd)
    got = server.reply(8)
    if "pid" in got:
        server.children.append(int(got["pid"]))
    assert server.proc.poll() is None, "a hostile packet ended the server"
    pid, stdin_write, report_read = server.fork(9)
    assert alive(pid)
    os.close(stdin_write)
    os.close(report_read)


def _flags(pid: int, fd: str) -> int:
    for line in Path(f"/proc/{pid}/fdinfo/{fd}").read_text().splitlines():
        if line.startswith("flags:"):
            return int(line.split()[1], 8)
    raise AssertionError(f"no flags for fd {fd}")


def test_a_forked_process_holds_no_server_socket_and_passes_no_descriptor_on(server: Server) -> None:
    pid, stdin_write, report_read = server.fork(1)
    # while it waits for its spec (settled: it closes the server's socket first thing after the fork),
    # it holds none of the server's sockets, and every descriptor past stdio is close-on-exec: a program
    # the component runs (os.system, a library's exec) must not get the launcher's report pipe
    time.sleep(1.0)
    assert not set(_sockets(pid)) & set(_sockets(server.proc.pid)), "the forked process kept the server's socket"
    leaked = [fd for fd in os.listdir(f"/proc/{pid}/fd") if int(fd) > 2 and not _flags(pid, fd) & _O_CLOEXEC]
    assert not leaked, {fd: os.readlink(f"/proc/{pid}/fd/{fd}") for fd in leaked}
    os.close(stdin_write)  # no spec: it reports why and ends
    with os.fdopen(report_read) as reports:
        assert "no complete component spec" in reports.readline()
    assert wait_for(lambda: not alive(pid), timeout=10, what="the child to end")


def test_an_endless_spec_line_is_refused_without_reading_it_all(server: Server) -> None:
    pid, stdin_write, report_read = server.fork(1)
    chunk = b"x" * 65536
    sent = 0
    with contextlib.suppress(BrokenPipeError):
        for _ in range(400):  # 25 MiB, no newline: past MAX_SPEC_BYTES
            os.write(stdin_write, chunk)
            sent += len(chunk)
    os.close(stdin_write)
    with os.fdopen(report_read) as reports:
        assert "no complete component spec" in reports.readline()
    assert wait_for(lambda: not alive(pid), timeout=10, what="the child to end")


def test_a_forked_process_ends_when_the_server_is_killed(server: Server) -> None:
    pid, stdin_write, report_read = server.fork(1)
    os.kill(server.proc.pid, signal.SIGKILL)
    server.proc.wait(timeout=10)
    assert wait_for(lambda: not alive(pid), timeout=10, what="the forked process to end (PR_SET_PDEATHSIG)")
    os.close(stdin_write)
    os.close(report_read)


def test_the_server_ends_when_its_launcher_end_closes(server: Server) -> None:
    pid, stdin_write, report_read = server.fork(1)
    server.sock.close()
    assert server.proc.wait(timeout=10) == 0
    assert wait_for(lambda: not alive(pid), timeout=10, what="the forked process to end")
    os.close(stdin_write)
    os.close(report_read)
