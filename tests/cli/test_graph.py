"""Graph discovery (``transport.discover()``) and the ``<name>/describe`` service on every transport.

A relay component is launched on transport ``a`` of a pair; transport ``b`` (another Zenoh
session, another ROS context) discovers it, then the component is stopped and disappears.
"""

from __future__ import annotations

import pytest

from agents_core import Launcher, Topic
from agents_core.errors import ServiceUnavailableError, TransportError
from agents_core.testing.helpers import wait_for
from agents_core.testing.pairs import memory_pair, missing_requirement, ros2_pair, zenoh_pair
from agents_core.transport import Graph, MemoryTransport, TopicInfo, describe_component
from agents_core.transport.core import DriverTransport
from agents_core.transport.memory import MemoryDriver
from tests.recipe_parts import Relay

PAIRS = {
    "memory": pytest.param(memory_pair, marks=pytest.mark.memory, id="memory"),
    "zenoh": pytest.param(zenoh_pair, marks=[pytest.mark.zenoh, pytest.mark.skipif(
        missing_requirement("zenoh") is not None, reason=str(missing_requirement("zenoh")))], id="zenoh"),
    "ros2": pytest.param(ros2_pair, marks=[pytest.mark.ros2, pytest.mark.skipif(
        missing_requirement("ros2") is not None, reason=str(missing_requirement("ros2")))], id="ros2"),
}


def _relay(name: str = "graph_relay") -> Relay:
    return Relay(inputs=[Topic("graph_in", "String")], outputs=[Topic("graph_out", "String")],
                 trigger=Topic("graph_in", "String"), component_name=name)


@pytest.mark.parametrize("pair", list(PAIRS.values()))
def test_discover_sees_topics_types_counts_and_components(pair) -> None:
    with pair() as (a, b):
        launcher = Launcher(transport=a)
        launcher.add_pkg([_relay()])
        launcher.start()
        try:
            extra_sub = b.create_subscription(Topic("graph_out", "String"), lambda _v: None)
            graph: Graph | None = None

            def complete() -> bool:
                nonlocal graph
                graph = b.discover(timeout=2.0)
                out = graph.topic("graph_out")
                return "graph_relay" in graph.components and out is not None and out.subscribers >= 1
            assert wait_for(complete, timeout=15.0), graph
            assert graph is not None
            assert graph.topic("graph_in") == TopicInfo(name="graph_in", msg_type="String", publishers=0,
                                                        subscribers=1)
            # One publisher (the relay); the subscriber is b's own (memory: the same instance).
            assert graph.topic("/graph_out") == TopicInfo(name="graph_out", msg_type="String", publishers=1,
                                                          subscribers=1)
            status = graph.topic("graph_relay/status")
            assert status is not None and status.msg_type == "ComponentStatus" and status.publishers == 1
            assert graph.to_dict()["components"] == graph.components
            extra_sub.close()

            described = describe_component(b, "graph_relay", timeout=5.0)
            assert described == {
                "name": "graph_relay", "component_type": "Relay", "run_type": "Event", "state": "active",
                "health": "HEALTHY", "inputs": [{"name": "graph_in", "msg_type": "String"}],
                "outputs": [{"name": "graph_out", "msg_type": "String"}], "actions": {},
            }
        finally:
            launcher.stop()
        # Gone from the graph once stopped.
        assert wait_for(lambda: "graph_relay" not in b.discover(timeout=1.0).components, timeout=15.0)
        assert wait_for(lambda: b.discover(timeout=1.0).topic("graph_out") is None, timeout=15.0)


def test_describe_lists_component_actions(memory: MemoryTransport) -> None:
    from agents_core.actions import component_action  # noqa: PLC0415

    class WithAction(Relay):
        @component_action(description={"type": "function", "function": {
            "name": "shout", "description": "say it loud", "parameters": {"type": "object", "properties": {}}}})
        def shout(self) -> str:
            return "HEY"

    component = WithAction(inputs=[Topic("a_in", "String")], outputs=[], trigger=Topic("a_in", "String"),
                           component_name="loud")
    launcher = Launcher(transport=memory)
    launcher.add_pkg([component])
    with launcher:
        described = describe_component(memory, "loud")
        assert described["component_type"] == "WithAction"
        assert described["actions"]["shout"]["function"]["description"] == "say it loud"
        assert described["outputs"] == []


def test_describe_of_a_missing_component_is_service_unavailable(memory: MemoryTransport) -> None:
    with pytest.raises(ServiceUnavailableError, match="nobody/describe"):
        describe_component(memory, "nobody", timeout=0.5)


def test_a_driver_without_discovery_says_so() -> None:
    class NoDiscover:
        """Delegates everything but discover() to a memory driver."""

        def __init__(self) -> None:
            self._inner = MemoryDriver()
            self.name = "blind"
            self.capabilities = self._inner.capabilities

        def __getattr__(self, item: str):
            if item == "discover":
                raise AttributeError(item)
            return getattr(self._inner, item)

    transport = DriverTransport(NoDiscover())  # type: ignore[arg-type]
    try:
        with pytest.raises(TransportError, match="blind transport does not support discovery"):
            transport.discover()
    finally:
        transport.close()


def test_memory_graph_forgets_closed_publishers(memory: MemoryTransport) -> None:
    pub = memory.create_publisher(Topic("temp", "Float32"))
    assert memory.discover().topic("temp") == TopicInfo(name="temp", msg_type="Float32", publishers=1)
    pub.close()
    assert memory.discover().topic("temp") is None


def test_describe_service_is_not_a_components_own_describe_method(memory: MemoryTransport) -> None:
    """MLLM has a ``describe(question)`` action: the service must still describe the component."""
    from agents_core.actions import component_action  # noqa: PLC0415

    class Describer(Relay):
        @component_action
        def describe(self, question: str = "what is it?") -> str:
            """Describe a picture."""
            return "a picture"

    component = Describer(inputs=[Topic("d_in", "String")], outputs=[], trigger=Topic("d_in", "String"),
                          component_name="describer")
    launcher = Launcher(transport=memory)
    launcher.add_pkg([component])
    with launcher:
        described = describe_component(memory, "describer")
        assert described["name"] == "describer" and "describe" in described["actions"]
        reply = memory.request("describer/execute_method", {"method": "describe", "args": ["q"]})
        assert reply == {"result": "a picture"}
