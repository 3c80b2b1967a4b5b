"""One process per component on ROS 2: real launcher and component processes (rclpy lifecycle nodes).

The launcher runs ``mp_recipe.py`` on the ros2 transport; the test watches the ROS graph with a
plain rclpy node of its own and drives the pipeline through an observer transport.
"""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from agents_core import Topic

from .helpers import SECRET, alive, recipe_run, wait_for

pytest.importorskip("rclpy")
pytestmark = [pytest.mark.ros2, pytest.mark.slow]

# The run's own domain when it sets one (ROS_DOMAIN_ID=...), else one derived from this process,
# as agents_core.testing.pairs does, so parallel runs on one host never see each other.
DOMAIN = int(os.environ.get("ROS_DOMAIN_ID") or 1 + os.getpid() % 100)


@pytest.fixture
def ros_env(monkeypatch: pytest.MonkeyPatch) -> dict[str, str]:
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN))
    return dict(os.environ)


@pytest.fixture
def graph(ros_env: dict[str, str]) -> Iterator[Any]:
    import rclpy  # noqa: PLC0415
    from rclpy.context import Context  # noqa: PLC0415
    from rclpy.signals import SignalHandlerOptions  # noqa: PLC0415

    import agents_ros2.conversions  # noqa: F401, PLC0415  # imports rosidl's parser with its warning silenced

    context = Context()
    rclpy.init(context=context, domain_id=DOMAIN, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("mp_graph_observer", context=context)
    try:
        yield node
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


@pytest.fixture
def observer(ros_env: dict[str, str]) -> Iterator[Any]:
    from agents_ros2.transport import Ros2Transport  # noqa: PLC0415

    transport = Ros2Transport(domain_id=DOMAIN)
    try:
        yield transport
    finally:
        transport.close()


def _nodes(graph: Any) -> set[str]:
    return {name for name, _ns in graph.get_node_names_and_namespaces()}


def _active(observer: Any, name: str) -> bool:
    try:
        status = observer.get_component_state(name, timeout=1.0)
    except Exception:  # the node is (re)appearing: its services are not matched yet
        return False
    return status is not None and status.lifecycle_state == "active"


def _answer(observer: Any, text: str, timeout: float = 20.0) -> str:
    got: list[str] = []
    sub = observer.create_subscription(Topic("mp/out", "String"), got.append)
    pub = observer.create_publisher(Topic("mp/in", "String"))
    try:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            pub.publish(text)
            until = time.monotonic() + 0.5
            while time.monotonic() < until:
                for answer in list(got):
                    if answer.startswith(text.upper()):
                        return answer
                time.sleep(0.02)
        raise AssertionError(f"no answer to {text!r} within {timeout} s")
    finally:
        sub.close()
        pub.close()


def test_ros2_components_in_processes_respawn_and_leave_the_graph(tmp_path: Path, ros_env: dict[str, str],
                                                                   graph: Any, observer: Any) -> None:
    with recipe_run(tmp_path, transport="ros2", env=ros_env) as run:
        pids = run.wait_children(2, timeout=60.0)
        wait_for(lambda: {"shout_a", "shout_b"} <= _nodes(graph), timeout=30.0, what="both nodes in the graph")
        wait_for(lambda: _active(observer, "shout_a") and _active(observer, "shout_b"), timeout=30.0,
                 what="both lifecycle nodes active")
        first = _answer(observer, "ros")
        for pid in (*pids, run.pid):
            assert SECRET.encode() not in Path(f"/proc/{pid}/cmdline").read_bytes()
            assert SECRET.encode() not in Path(f"/proc/{pid}/environ").read_bytes()
        victim = int(first.split("[")[2].split("]")[0])
        assert victim in pids
        # Respawns are off for this check: the dead node must leave the graph (not be replaced).
        os.kill(victim, signal.SIGKILL)
        killed_at = time.monotonic()
        wait_for(lambda: victim not in run.children() or not alive(victim), timeout=5.0, what="the victim gone")
        wait_for(lambda: _active(observer, "shout_b") and victim not in run.children(), timeout=30.0,
                 what="shout_b active again in a new process")
        print(f"shout_b active again {time.monotonic() - killed_at:.2f} s after SIGKILL")
        second = _answer(observer, "again")
        assert int(second.split("[")[2].split("]")[0]) != victim
        # Stop with the max_retries spent: give the launcher SIGTERM; every node leaves the graph.
        run.proc.send_signal(signal.SIGTERM)
        assert run.proc.wait(timeout=30.0) == 0
        wait_for(lambda: "shout_a" not in _nodes(graph), timeout=15.0, what="shout_a gone from the graph",
                 step=0.1)
        # shout_b's SIGKILLed participant stays listed until Fast DDS's lease (20 s) after the kill.
        wait_for(lambda: "shout_b" not in _nodes(graph), timeout=max(1.0, 35.0 - (time.monotonic() - killed_at)),
                 what="shout_b gone from the graph", step=0.1)
    assert SECRET not in run.log()


def test_ros2_node_of_a_crashed_child_leaves_the_graph_when_not_respawned(tmp_path: Path, ros_env: dict[str, str],
                                                                          graph: Any, observer: Any) -> None:
    with recipe_run(tmp_path, transport="ros2", retries=0, env=ros_env) as run:
        run.wait_children(2, timeout=60.0)
        wait_for(lambda: _active(observer, "shout_a") and _active(observer, "shout_b"), timeout=30.0,
                 what="both lifecycle nodes active")
        victim = int(_answer(observer, "bye").split("[")[2].split("]")[0])
        os.kill(victim, signal.SIGKILL)
        killed_at = time.monotonic()
        wait_for(lambda: "GAVE_UP" in run.output(), timeout=10.0, what="the give-up with max_retries=0")
        # Fast DDS drops a participant that vanished without saying goodbye after its lease.
        wait_for(lambda: "shout_b" not in _nodes(graph), timeout=30.0, what="shout_b gone from the graph",
                 step=0.1)
        print(f"shout_b left the graph {time.monotonic() - killed_at:.2f} s after SIGKILL")
        assert "shout_a" in _nodes(graph)
