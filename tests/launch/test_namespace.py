"""``Launcher(namespace=...)``: one recipe run as two robots on one transport, as ROS 2 namespaces resolve names.

Two launchers run the same recipe under ``robot1`` and ``robot2`` on one memory transport (what a
fleet does through a router, in one process); an operator with no namespace sees both robots'
components and topics under their namespaces, addresses each one's services (``execute_method``,
lifecycle, status), and shares the absolute topic ``/map`` with both. The same on Zenoh across a
component process, and on ROS 2 with the real node namespace, are below; the network-namespace
fleet test is ``tests/fleet``.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator
from typing import Any

import pytest

from agents_core import Launcher, Topic
from agents_core.actions import component_action
from agents_core.components import Component
from agents_core.errors import ConfigError
from agents_core.testing.pairs import missing_requirement
from agents_core.transport import MemoryTransport
from agents_core.transport.namespace import namespaced, resolve_name, validate_namespace
from tests.conftest import free_tcp_port, wait_for

BATTERY = Topic("battery", "Float32")
MAP = Topic("/map", "String")


class Battery(Component):
    """Reports a charge on ``battery`` and the robot's name on the shared ``/map``."""

    def __init__(self, **kwargs: Any) -> None:
        self.charge = 100.0
        self.robot = "?"
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        self.charge = max(0.0, self.charge - 1.0)
        self.publishers_dict["battery"].publish(self.charge)
        self.publishers_dict["/map"].publish(f"seen by {self.label}")

    @component_action
    def recharge(self, to: float) -> str:
        """Set the charge."""
        self.charge = float(to)
        return f"{self.label} charged to {self.charge:g}"

    @property
    def label(self) -> str:
        return self.robot


def robot(name: str, transport: Any) -> Launcher:
    """The one recipe every robot runs, under namespace ``name``."""
    launcher = Launcher(transport=transport, namespace=name, quiet=True)
    battery = Battery(inputs=[], outputs=[BATTERY, MAP], trigger=20.0, component_name="battery")
    battery.robot = name
    launcher.add_pkg(components=[battery])
    return launcher


@pytest.fixture
def fleet(memory: MemoryTransport) -> Iterator[list[Launcher]]:
    robots = [robot("robot1", memory), robot("robot2", memory)]
    try:
        for r in robots:
            r.start()
        yield robots
    finally:
        for r in robots:
            r.stop()


def test_two_robots_from_one_recipe_do_not_collide_and_an_operator_sees_each(
        memory: MemoryTransport, fleet: list[Launcher]) -> None:
    charges: dict[str, list[float]] = {"robot1": [], "robot2": []}
    seen: list[str] = []
    for name, values in charges.items():
        memory.create_subscription(Topic(f"{name}/battery", "Float32"), values.append)
    memory.create_subscription(Topic("map", "String"), seen.append)  # /map is shared: no namespace on it
    assert wait_for(lambda: all(len(v) >= 3 for v in charges.values()), timeout=10.0), charges
    assert wait_for(lambda: {"seen by robot1", "seen by robot2"} <= set(seen), timeout=10.0), seen

    graph = memory.discover(0.1)
    assert sorted(graph.components) == ["robot1/battery", "robot2/battery"]
    names = {t.name for t in graph.topics}
    assert {"robot1/battery", "robot2/battery", "map", "robot1/battery/status", "robot2/battery/status"} <= names
    assert "battery" not in names and "/map" not in names

    # Each robot's own services carry its namespace: execute_method, lifecycle, state.
    reply = memory.request("robot2/battery/execute_method", {"method": "recharge", "args": [42], "kwargs": {}},
                           timeout=5.0)
    assert reply["result"] == "robot2 charged to 42"
    assert wait_for(lambda: charges["robot2"][-1] < 42.0, timeout=10.0)
    assert charges["robot1"][-1] > 42.0  # robot1 was not touched
    described = memory.request("robot1/battery/describe", {}, timeout=5.0)  # what an observer must use
    assert described["name"] == "robot1/battery"
    assert [t["name"] for t in described["outputs"]] == ["robot1/battery", "map"]
    state = memory.get_component_state("robot1/battery", timeout=2.0)
    assert state is not None and state.component == "robot1/battery" and state.lifecycle_state == "active"
    assert memory.request_transition("robot1/battery", "deactivate", timeout=5.0)
    assert wait_for(lambda: fleet[0].components[0].lifecycle_state.value == "inactive", timeout=5.0)
    assert fleet[1].components[0].lifecycle_state.value == "active"


def test_inside_a_robot_names_stay_local(memory: MemoryTransport, fleet: list[Launcher]) -> None:
    """The robot's own view (``launcher.transport``) resolves names in its namespace, as a node in it does."""
    inside = fleet[0].transport
    got: list[float] = []
    inside.create_subscription(BATTERY, got.append)  # robot1/battery, not robot2's
    assert wait_for(lambda: len(got) >= 2, timeout=10.0)
    assert inside.request("battery/execute_method", {"method": "recharge", "args": [7], "kwargs": {}},
                          timeout=5.0)["result"] == "robot1 charged to 7"
    assert sorted(inside.discover(0.1).components) == ["robot1/battery", "robot2/battery"]  # the whole graph


def test_the_namespace_is_part_of_the_recipe_and_read_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    assert robot("robot1", "memory").recipe.to_dict()["settings"]["namespace"] == "robot1"
    monkeypatch.setenv("AGENTS_NAMESPACE", "/site_a/robot3/")
    assert Launcher(transport="memory").recipe.settings.namespace == "site_a/robot3"
    monkeypatch.delenv("AGENTS_NAMESPACE")
    assert Launcher(transport="memory").recipe.settings.namespace == ""


@pytest.mark.parametrize("bad", ["robot-1", "robot 1", "1robot", "a//b", "robot.1", "**", "@agents"])
def test_an_invalid_namespace_is_refused_naming_the_field(bad: str) -> None:
    with pytest.raises(ConfigError, match=r"Launcher\(namespace=\.\.\.\)") as caught:
        Launcher(transport="memory", namespace=bad)
    assert repr(bad) in str(caught.value)


def test_a_namespace_of_the_wrong_type_and_a_bad_environment_are_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(ConfigError, match=r"Launcher\(namespace=\.\.\.\) must be a str"):
        Launcher(transport="memory", namespace=3)  # type: ignore[arg-type]
    monkeypatch.setenv("AGENTS_NAMESPACE", "robot-1")
    with pytest.raises(ConfigError, match="AGENTS_NAMESPACE 'robot-1'"):
        Launcher(transport="memory")


def test_names_resolve_as_ros2_resolves_them() -> None:
    assert resolve_name("robot1", "camera") == "robot1/camera"
    assert resolve_name("robot1", "arm/status") == "robot1/arm/status"
    assert resolve_name("robot1", "/map") == "map"
    assert resolve_name("", "camera") == "camera"
    assert validate_namespace(" /robot1/ ") == "robot1"
    assert validate_namespace("") == "" and validate_namespace(None) == ""


def test_a_view_leaves_a_transport_it_does_not_own_open(memory: MemoryTransport) -> None:
    view = namespaced(memory, "robot9")
    got: list[float] = []
    memory.create_subscription(Topic("robot9/battery", "Float32"), got.append)
    view.create_publisher(BATTERY).publish(1.0)
    assert wait_for(lambda: got == [1.0], timeout=5.0)
    view.close()
    assert not memory.closed
    assert namespaced(memory, "") is memory


# -- Zenoh: a component process under the namespace, an observer in this one -----------------------------


@pytest.mark.zenoh
@pytest.mark.skipif(missing_requirement("zenoh") is not None, reason=str(missing_requirement("zenoh")))
def test_a_component_process_runs_in_the_namespace_on_zenoh() -> None:
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    options = {"mode": "peer", "listen": [endpoint], "connect": [], "multicast_scouting": False}
    launcher = Launcher(transport="zenoh", transport_options=options, namespace="robot1", quiet=True)
    launcher.add_pkg(components=[Battery(inputs=[], outputs=[BATTERY, MAP], trigger=20.0,
                                         component_name="battery")], multiprocessing=True)
    from agents_core.transport.registry import resolve_transport  # noqa: PLC0415

    with launcher:
        observer = resolve_transport("zenoh", mode="client", connect=[endpoint], multicast_scouting=False)
        try:
            got: list[float] = []
            done = threading.Event()

            def heard(value: Any) -> None:
                got.append(value)
                done.set()

            observer.create_subscription(Topic("robot1/battery", "Float32"), heard)
            assert done.wait(30.0), "no robot1/battery sample from the component process"
            assert wait_for(lambda: "robot1/battery" in observer.discover(0.5).components, timeout=10.0)
            reply = observer.request("robot1/battery/execute_method",
                                     {"method": "recharge", "args": [50], "kwargs": {}}, timeout=10.0)
            assert reply["result"] == "? charged to 50"  # (no robot attribute is set in this recipe)
            assert launcher.supervisor is not None and launcher.all_active()
        finally:
            observer.close()


# -- ROS 2: the component's node lives in the namespace ------------------------------------------------


@pytest.mark.ros2
@pytest.mark.skipif(missing_requirement("ros2") is not None, reason=str(missing_requirement("ros2")))
def test_on_ros2_the_component_node_gets_the_real_namespace() -> None:
    from agents_core.testing.pairs import ros2_pair  # noqa: PLC0415

    suffix = f"{os.getpid()}"
    with ros2_pair() as (a, b):
        launcher = Launcher(transport=a, namespace=f"robot_{suffix}", quiet=True)
        launcher.add_pkg(components=[Battery(inputs=[], outputs=[BATTERY, MAP], trigger=20.0,
                                             component_name="battery")])
        with launcher:
            node = b.driver.node  # type: ignore[attr-defined]
            assert wait_for(lambda: ("battery", f"/robot_{suffix}") in node.get_node_names_and_namespaces(),
                            timeout=20.0), node.get_node_names_and_namespaces()
            topics = dict(node.get_topic_names_and_types())
            assert wait_for(lambda: f"/robot_{suffix}/battery" in dict(node.get_topic_names_and_types()),
                            timeout=20.0), topics
            state = b.get_component_state(f"robot_{suffix}/battery", timeout=10.0)
            assert state is not None and state.lifecycle_state == "active"
            reply = b.request(f"robot_{suffix}/battery/execute_method",
                              {"method": "recharge", "args": [3], "kwargs": {}}, timeout=10.0)
            assert reply["result"] == "? charged to 3"
