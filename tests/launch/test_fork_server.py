"""Component processes forked by the pre-imported fork server (:mod:`agents_core.launch.fork_server`).

The launcher runs in this test process on Zenoh (loopback, no scouting). What is checked is
what the server promises: a component process is the server's child, built from a module the
server imported (not the child), respawned through the server, never shows its secret in argv or
the environment, and dies with its launcher; ``process_start="spawn"`` (or
``AGENTS_PROCESS_START=spawn``) starts fresh interpreters as before.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from agents_core.errors import ConfigError
from agents_core.launch.fork_server import PROCESS_START_ENV, ForkedProcess, ForkServer, fork_available, fork_server
from agents_core.launch.launcher import Launcher
from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.pairs import skip_unless_installed

from .forked_components import WhereAmI
from .helpers import REPO, alive, ask_where, kill_and_wait_for_respawn, parent_pid, wait_for

pytestmark = [pytest.mark.zenoh, pytest.mark.skipif(not fork_available(), reason="the fork server needs Linux")]

SECRET = "fork-server-secret-4471"


def _launcher(prefix: str, **options: Any) -> Launcher:
    skip_unless_installed("zenoh")
    launcher = Launcher(transport="zenoh", quiet=True, transport_options={
        "mode": "peer", "listen": [f"tcp/127.0.0.1:{free_tcp_port()}"], "connect": [],
        "multicast_scouting": False}, **options)
    launcher.add_pkg(components=[WhereAmI(f"{prefix}/in", f"{prefix}/out", f"{prefix}_where", token=SECRET)],
                     multiprocessing=True)
    return launcher


@pytest.fixture
def started() -> Iterator[Launcher]:
    launcher = _launcher("fs")
    launcher.on_process_fail(max_retries=2)
    launcher.start()
    try:
        yield launcher
    finally:
        launcher.stop()


def test_a_forked_component_uses_the_module_the_server_imported(started: Launcher) -> None:
    supervisor = started.supervisor
    assert supervisor is not None
    child = supervisor.children[0]
    server = fork_server()
    assert isinstance(child.proc, ForkedProcess)
    assert child.pid is not None and parent_pid(child.pid) == server.pid
    imported_in, pid = ask_where(started, "fs")
    assert pid == child.pid
    assert imported_in == server.pid != pid  # imported once, in the server, before the fork


def test_a_respawn_goes_through_the_server(started: Launcher) -> None:
    child = kill_and_wait_for_respawn(started, timeout=20.0)
    assert isinstance(child.proc, ForkedProcess)
    assert child.pid is not None and parent_pid(child.pid) == fork_server().pid
    assert ask_where(started, "fs")[1] == child.pid


def test_no_secret_in_the_forked_process_or_the_server_argv_or_environment(started: Launcher) -> None:
    supervisor = started.supervisor
    assert supervisor is not None
    pid = supervisor.children[0].pid
    assert pid is not None
    ask_where(started, "fs")  # the component was built from its spec (which holds the token)
    for proc in (pid, fork_server().pid):
        for what in ("cmdline", "environ"):
            assert SECRET.encode() not in Path(f"/proc/{proc}/{what}").read_bytes(), (proc, what)


def test_process_start_spawn_starts_fresh_interpreters(monkeypatch: pytest.MonkeyPatch) -> None:
    for options, env in (({"process_start": "spawn"}, None), ({}, "spawn")):
        if env is not None:
            monkeypatch.setenv(PROCESS_START_ENV, env)
        launcher = _launcher("sp", **options)
        launcher.start()
        try:
            supervisor = launcher.supervisor
            assert supervisor is not None
            child = supervisor.children[0]
            assert isinstance(child.proc, subprocess.Popen)
            assert child.pid is not None and parent_pid(child.pid) == os.getpid()
            imported_in, pid = ask_where(launcher, "sp")
            assert imported_in == pid == child.pid
        finally:
            launcher.stop()


def test_an_unknown_process_start_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(ConfigError, match="'fork' or 'spawn'"):
        Launcher(transport="zenoh", process_start="vfork")
    monkeypatch.setenv(PROCESS_START_ENV, "threads")
    with pytest.raises(ConfigError, match=PROCESS_START_ENV):
        Launcher(transport="zenoh")


LAUNCHER = """
import sys, time
sys.path.insert(0, {repo!r})
from agents_core.launch.launcher import Launcher
from tests.launch.forked_components import WhereAmI
launcher = Launcher(transport="zenoh", quiet=True, transport_options={{"mode": "peer",
    "listen": ["tcp/127.0.0.1:{port}"], "connect": [], "multicast_scouting": False}})
launcher.add_pkg(components=[WhereAmI("dl/in", "dl/out", "dl_where")], multiprocessing=True)
launcher.start()
print("PIDS", launcher.supervisor.children[0].pid, flush=True)
time.sleep(600)
"""


def test_a_forked_child_and_the_server_die_with_a_killed_launcher(tmp_path: Path) -> None:
    skip_unless_installed("zenoh")
    script = tmp_path / "launcher.py"
    script.write_text(LAUNCHER.format(repo=str(REPO), port=free_tcp_port()))
    with (tmp_path / "launcher.log").open("wb") as log:
        proc = subprocess.Popen([sys.executable, str(script)], cwd=REPO, stdout=subprocess.PIPE, stderr=log,
                                text=True)
    pids: list[int] = []
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line.startswith("PIDS"), (tmp_path / "launcher.log").read_text()[-3000:]
        child = int(line.split()[1])
        server = parent_pid(child)
        pids = [child, server]
        assert server != proc.pid and parent_pid(server) == proc.pid  # forked by the server, not the launcher
        proc.kill()
        proc.wait(timeout=5.0)
        killed = time.monotonic()
        wait_for(lambda: not [p for p in pids if alive(p)], timeout=5.0, what="the child and the server to exit")
        print(f"gone {time.monotonic() - killed:.2f} s after the launcher's SIGKILL")
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=5.0)
        if proc.stdout is not None:
            proc.stdout.close()
        for pid in pids:
            if alive(pid):
                os.kill(pid, signal.SIGKILL)


def test_a_pass_of_the_server_that_fails_is_logged_and_the_server_goes_on(capfd: pytest.CaptureFixture[str]) -> None:
    """A bad pass (here a packet too deeply nested for ``json.loads``: RecursionError, not ValueError)
    used to end the server, and every component process with it (review s9, finding 1)."""
    server = ForkServer()
    report_read, report_write = os.pipe()
    stdin_read, stdin_write = os.pipe()
    try:
        server._sock.send(b"[" * 20_000 + b"]" * 20_000)
        child = server.fork("after-a-bad-pass", stdin_read, report_write, stdin_write)
        assert child.stdin is not None
        child.stdin.close()  # its command pipe ends at once: the forked process exits
        assert child.wait(timeout=10.0) is not None, "its end was reported by the server"
        assert server.proc.poll() is None and not server.gone
        assert "a pass of its loop failed" in capfd.readouterr().err
    finally:
        server.close()
        for fd in (report_read, report_write, stdin_read):
            os.close(fd)
