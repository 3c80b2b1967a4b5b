"""What a transport adapter's ``fork_support`` module adds to the fork server.

The hooks run around each fork in the order the server promises (and a refusal makes the fork
fail, which the launcher answers with a fresh interpreter); on ROS 2 the server imports rclpy
and the adapter before it forks (with no context: the component process initialises rclpy), and
a forked ROS 2 component answers on ROS 2, respawns through the server and keeps its secret out
of argv and the environment.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace

import pytest

from agents_core.launch import fork_server as fs
from agents_core.launch.fork_server import ForkedProcess, fork_available, fork_server
from agents_core.launch.launcher import Launcher
from agents_core.testing.pairs import skip_unless_installed

from .forked_components import WhereAmI
from .helpers import ask_where, kill_and_wait_for_respawn, parent_pid

pytestmark = pytest.mark.skipif(not fork_available(), reason="the fork server needs Linux")

SECRET = "ros2-fork-secret-9113"


def _support(name: str, calls: list[str], refuse: bool = False) -> SimpleNamespace:
    def before_fork() -> None:
        calls.append(f"{name}:before")
        if refuse:
            raise RuntimeError(f"{name} refuses")

    return SimpleNamespace(before_fork=before_fork, after_fork_parent=lambda: calls.append(f"{name}:parent"),
                           after_fork_child=lambda: calls.append(f"{name}:child"))


def test_the_hooks_run_around_the_fork_in_both_processes(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[str] = []
    monkeypatch.setattr(fs, "_fork_supports", [_support("a", calls), _support("b", calls)])
    read_end, write_end = os.pipe()
    pid = fs._fork()
    if pid == 0:  # the child: say which hooks ran here, and leave at once
        os.write(write_end, ",".join(calls).encode())
        os._exit(0)
    os.close(write_end)
    try:
        child_calls = os.read(read_end, 4096).decode()
    finally:
        os.close(read_end)
        os.waitpid(pid, 0)
    assert child_calls == "a:before,b:before,a:child,b:child"
    assert calls == ["a:before", "b:before", "a:parent", "b:parent"]


def test_a_refusing_hook_stops_the_fork_and_the_others_are_released(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[str] = []
    monkeypatch.setattr(fs, "_fork_supports", [_support("a", calls), _support("b", calls, refuse=True),
                                               _support("c", calls)])
    children_before = set(os.listdir("/proc/self/task"))
    with pytest.raises(RuntimeError, match="b refuses"):
        fs._fork()
    # a was prepared and is released; b refused (no after_*), c was never asked.
    assert calls == ["a:before", "b:before", "a:parent"]
    assert set(os.listdir("/proc/self/task")) == children_before


def test_ros2_fork_support_refuses_a_server_with_rclpy_initialised() -> None:
    skip_unless_installed("ros2")
    import rclpy  # noqa: PLC0415

    from agents_ros2 import fork_support  # noqa: PLC0415

    if rclpy.ok():
        pytest.skip("rclpy's default context is initialised by another test")
    fork_support.before_fork()  # not initialised: allowed
    fork_support.after_fork_parent()
    rclpy.init(domain_id=int(os.environ.get("ROS_DOMAIN_ID") or 1 + os.getpid() % 100))
    try:
        with pytest.raises(RuntimeError, match="initialised"):
            fork_support.before_fork()
    finally:
        rclpy.shutdown()


def _ros2_launcher() -> Launcher:
    skip_unless_installed("ros2")
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    launcher = Launcher(transport="ros2", quiet=True)
    launcher.add_pkg(components=[WhereAmI("r2fs/in", "r2fs/out", "r2fs_where", token=SECRET)], multiprocessing=True)
    return launcher


@pytest.fixture
def ros2_started(monkeypatch: pytest.MonkeyPatch) -> Iterator[Launcher]:
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    launcher = _ros2_launcher()
    launcher.on_process_fail(max_retries=2)
    launcher.start()
    try:
        yield launcher
    finally:
        launcher.stop()


def _maps(pid: int) -> str:
    return Path(f"/proc/{pid}/maps").read_text(errors="replace")


@pytest.mark.ros2
def test_a_ros2_component_is_forked_from_a_server_that_imported_rclpy_without_a_context(
        ros2_started: Launcher) -> None:
    supervisor = ros2_started.supervisor
    assert supervisor is not None
    child = supervisor.children[0]
    server = fork_server().pid
    assert isinstance(child.proc, ForkedProcess)
    assert child.pid is not None and parent_pid(child.pid) == server
    # rclpy's extension is loaded in the server (imported once, before the fork) ...
    assert "_rclpy_pybind11" in _maps(server)
    # ... but no DDS participant exists there: no Fast DDS segment, no participant threads.
    assert "/dev/shm/fastrtps_" not in _maps(server)
    assert "/dev/shm/fastrtps_" in _maps(child.pid) or len(os.listdir(f"/proc/{child.pid}/task")) > len(
        os.listdir(f"/proc/{server}/task"))
    imported_in, pid = ask_where(ros2_started, "r2fs", timeout=30.0)
    assert imported_in == server and pid == child.pid
    for proc in (child.pid, server):
        for what in ("cmdline", "environ"):
            assert SECRET.encode() not in Path(f"/proc/{proc}/{what}").read_bytes(), (proc, what)


@pytest.mark.ros2
def test_a_ros2_respawn_is_forked_by_the_server_and_answers(ros2_started: Launcher) -> None:
    child = kill_and_wait_for_respawn(ros2_started, timeout=30.0)
    assert isinstance(child.proc, ForkedProcess) and parent_pid(child.pid) == fork_server().pid
    assert ask_where(ros2_started, "r2fs", timeout=30.0)[1] == child.pid


def test_the_adapter_module_is_found_for_names_and_transport_objects() -> None:
    assert fs.adapter_module("ros2") == "agents_ros2.transport"
    assert fs.adapter_module("zenoh") == "agents_zenoh.transport"
    assert fs.adapter_module("no-such-transport") is None
    # A transport object: its own class's module, or its driver's when the class is the core's wrapper.
    assert fs.adapter_module(WhereAmI.__new__(WhereAmI)) == "tests.launch.forked_components"
    from agents_core.transport.core import DriverTransport  # noqa: PLC0415

    wrapper = DriverTransport.__new__(DriverTransport)
    wrapper.driver = _support("x", [])  # type: ignore[assignment]  # any object from another module
    assert fs.adapter_module(wrapper) == "types"
