"""A forked component process sees the launcher's environment as it is when the component starts.

The fork server is started once per launcher process, with the launcher's environment of then;
the changes since travel with each spec (:mod:`agents_core.launch.fork_environment`). Two
launches in this process, on Zenoh (loopback, no scouting), with a variable changed in between:
the second launch's process reports the new value, and so does a respawn after a further change.
On ROS 2, the second launch is in another domain (``ROS_DOMAIN_ID`` changed): its forked process
joins it, and the launcher discovers it there.
A change the server's preloaded modules cannot see (a thread-pool variable numpy read at import)
makes the component start in a fresh interpreter instead.
"""

from __future__ import annotations

import os
import time
from typing import Any

import pytest

from agents_core import Topic
from agents_core.components.component_base import Component
from agents_core.launch.fork_environment import MAX_ENVIRONMENT_BYTES, CannotCarry, environment_changes
from agents_core.launch.fork_server import ForkedProcess, ForkServerError, fork_available, fork_server
from agents_core.launch.launcher import Launcher
from agents_core.launch.spec import ComponentSpec
from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.pairs import skip_unless_installed

from .forked_components import ReadsEnvironment
from .helpers import kill_and_wait_for_respawn, wait_for

pytestmark = pytest.mark.skipif(not fork_available(), reason="the fork server needs Linux")

VARIABLE = "AGENTS_TEST_FORK_ENVIRONMENT"


def _launcher(prefix: str) -> Launcher:
    skip_unless_installed("zenoh")
    launcher = Launcher(transport="zenoh", quiet=True, transport_options={
        "mode": "peer", "listen": [f"tcp/127.0.0.1:{free_tcp_port()}"], "connect": [],
        "multicast_scouting": False})
    launcher.add_pkg(components=[ReadsEnvironment(f"{prefix}/in", f"{prefix}/out", f"{prefix}_env")],
                     multiprocessing=True)
    return launcher


def _ask(launcher: Launcher, prefix: str, name: str, timeout: float = 20.0) -> tuple[str, int]:
    """The value of ``name`` in the component process's environment, and that process's pid."""
    got: list[str] = []
    sub = launcher.transport.create_subscription(Topic(f"{prefix}/out", "String"), got.append)
    pub = launcher.transport.create_publisher(Topic(f"{prefix}/in", "String"))
    try:
        wait_for(lambda: pub.publish(name) or got, timeout=timeout, what=f"an answer on {prefix}/out", step=0.2)
    finally:
        sub.close()
    value, _, pid = got[0].rpartition(":")
    return value, int(pid)


def _child(launcher: Launcher) -> Any:
    supervisor = launcher.supervisor
    assert supervisor is not None
    return supervisor.children[0]


@pytest.mark.zenoh
def test_a_second_launch_and_a_respawn_see_the_environment_of_their_start(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(VARIABLE, "first")
    server = fork_server()  # started now (or earlier in this session): its environment is that of then
    first = _launcher("fenv1")
    first.start()
    try:
        assert isinstance(_child(first).proc, ForkedProcess)
        assert _ask(first, "fenv1", VARIABLE)[0] == "first"
    finally:
        first.stop()
    monkeypatch.setenv(VARIABLE, "second")
    second = _launcher("fenv2")
    second.on_process_fail(max_retries=2)
    second.start()
    try:
        child = _child(second)
        assert isinstance(child.proc, ForkedProcess) and fork_server() is server  # the same server, forked by it
        assert _ask(second, "fenv2", VARIABLE) == ("second", child.pid)
        monkeypatch.delenv(VARIABLE)
        child = kill_and_wait_for_respawn(second, timeout=20.0)
        assert isinstance(child.proc, ForkedProcess)
        assert _ask(second, "fenv2", VARIABLE) == ("<unset>", child.pid)  # removed since: removed there
    finally:
        second.stop()
    assert server.environment.get(VARIABLE) in (None, "first")  # the server's own environment never changed


@pytest.mark.zenoh
def test_a_variable_read_at_preload_changed_means_a_fresh_interpreter(monkeypatch: pytest.MonkeyPatch) -> None:
    server = fork_server()
    value = "3" if server.environment.get("OPENBLAS_NUM_THREADS") != "3" else "2"
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", value)
    launcher = _launcher("fenv3")
    started = time.monotonic()
    launcher.start()
    try:
        child = _child(launcher)
        assert not isinstance(child.proc, ForkedProcess)  # spawned: a forked one would keep numpy's pool size
        assert _ask(launcher, "fenv3", "OPENBLAS_NUM_THREADS", timeout=max(5.0, 60.0 - (time.monotonic() - started))
                    ) == (value, child.pid)
    finally:
        launcher.stop()


@pytest.mark.ros2
def test_a_ros2_component_process_joins_the_domain_of_its_launch(monkeypatch: pytest.MonkeyPatch) -> None:
    skip_unless_installed("ros2")
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    for index, domain in enumerate((1 + os.getpid() % 100, 1 + (os.getpid() + 50) % 100)):
        monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
        launcher = Launcher(transport="ros2", quiet=True)
        launcher.add_pkg(components=[ReadsEnvironment(f"r2env{index}/in", f"r2env{index}/out", f"r2env{index}")],
                         multiprocessing=True)
        launcher.start()
        try:
            child = _child(launcher)
            assert isinstance(child.proc, ForkedProcess)
            # Answered: the launcher's node, in the new domain, discovered the component's.
            assert _ask(launcher, f"r2env{index}", "ROS_DOMAIN_ID", timeout=30.0) == (str(domain), child.pid)
        finally:
            launcher.stop()
    monkeypatch.setenv("RMW_IMPLEMENTATION", "rmw_another_cpp")  # loaded with rclpy, in the server: fixed
    with pytest.raises(ForkServerError, match="RMW_IMPLEMENTATION"):
        fork_server().environment_changes()


def test_the_changes_name_what_was_added_changed_and_removed_and_are_bounded() -> None:
    start = {"KEPT": "1", "CHANGED": "old", "REMOVED": "x"}
    assert environment_changes(start, (), {"KEPT": "1", "CHANGED": "new", "ADDED": "y"}) == {
        "CHANGED": "new", "ADDED": "y", "REMOVED": None}
    assert environment_changes(start, ("KEPT",), dict(start)) == {}
    with pytest.raises(CannotCarry, match="FIXED"):
        environment_changes({}, ("FIXED",), {"FIXED": "1"})
    with pytest.raises(CannotCarry, match="bytes"):
        environment_changes({}, (), {"BIG": "x" * (MAX_ENVIRONMENT_BYTES + 1)})


def test_the_spec_applies_the_changes_and_refuses_what_is_not_an_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AGENTS_TEST_REMOVED", "x")
    spec = ComponentSpec.from_dict({**_spec_data(), "environment": {VARIABLE: "set", "AGENTS_TEST_REMOVED": None}})
    spec.apply_environment()
    assert os.environ[VARIABLE] == "set" and "AGENTS_TEST_REMOVED" not in os.environ
    monkeypatch.delenv(VARIABLE)
    with pytest.raises(Exception, match="must be a string"):
        ComponentSpec.from_dict({**_spec_data(), "environment": {VARIABLE: 3}}).apply_environment()


def _spec_data() -> dict[str, Any]:
    data = ComponentSpec(component_name="c", component_class=f"{Component.__module__}:Component", args=[],
                         kwargs={}, transport="memory", transport_options={}).to_dict()
    assert data["environment"] is None  # a spawned process's: it inherits the launcher's
    return data
