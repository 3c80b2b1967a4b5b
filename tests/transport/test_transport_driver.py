"""A third party's driver: the required primitives on DriverBase make a transport; capabilities follow the overrides."""

from __future__ import annotations

from typing import Any

import pytest

from agents_core.errors import ServiceUnavailableError, TransportError
from agents_core.messages import ComponentStatusMsg
from agents_core.status import HealthStatus, LifecycleState
from agents_core.topics import Topic
from agents_core.transport import DriverBase, DriverTransport, TransportCapabilities, registry, resolve_transport
from agents_core.transport.driver import (
    DriverActionServer,
    DriverGoal,
    GoalEvents,
    GoalServerHooks,
    Lane,
    ServiceHandler,
    Sink,
    TransitionHandler,
)
from agents_core.transport.goals import ActionType, GoalHandle, GoalStatus
from agents_core.transport.memory import MemoryDriver

VLA = "VisionLanguageAction"


class _Handle:
    def __init__(self, on_close: Any = None, send: Any = None) -> None:
        self._on_close = on_close
        self._send = send

    def send(self, value: Any) -> None:
        self._send(value)

    def update(self, state: LifecycleState, health: HealthStatus, message: str) -> None:
        pass

    def close(self) -> None:
        if self._on_close is not None:
            self._on_close()


class MinimalDriver(DriverBase):
    """Only the required primitives, in one process (what a third party writes first)."""

    name = "minimal"

    def __init__(self) -> None:
        self.sinks: dict[str, list[Sink]] = {}
        self.services: dict[str, tuple[ServiceHandler, Lane]] = {}
        self.components: set[str] = set()

    def open_publisher(self, topic: Topic, owner: str | None) -> _Handle:
        return _Handle(send=lambda value: [sink.offer(value) for sink in self.sinks.get(topic.name, [])])

    def open_subscriber(self, topic: Topic, sink: Sink, owner: str | None) -> _Handle:
        self.sinks.setdefault(topic.name, []).append(sink)
        return _Handle(on_close=lambda: self.sinks[topic.name].remove(sink))

    def serve(self, name: str, handler: ServiceHandler, owner: str | None, lane: Lane) -> _Handle:
        self.services[name] = (handler, lane)
        return _Handle(on_close=lambda: self.services.pop(name, None))

    def call(self, name: str, payload: dict[str, Any], timeout: float) -> dict[str, Any]:
        if name not in self.services:
            raise ServiceUnavailableError(f"nobody serves {name!r}")
        return self.services[name][0](payload)  # on the caller's thread: enough for this test

    def declare_presence(self, name: str, on_transition: TransitionHandler, lane: Lane) -> _Handle:
        self.components.add(name)
        return _Handle(on_close=lambda: self.components.discard(name))

    def read_state(self, name: str, timeout: float) -> ComponentStatusMsg | None:
        return ComponentStatusMsg(component=name, lifecycle_state="unconfigured", health="HEALTHY") \
            if name in self.components else None

    def request_transition(self, name: str, transition: str, timeout: float) -> bool:
        raise ServiceUnavailableError(f"no component {name!r}")

    def close(self) -> None:
        self.sinks.clear()


class GoalsDriver(MinimalDriver):
    """The minimal driver plus the two goal primitives (carried by a memory driver)."""

    name = "goals"

    def __init__(self) -> None:
        super().__init__()
        self._goals = MemoryDriver()

    def serve_goals(self, name: str, definition: ActionType, hooks: GoalServerHooks, owner: str | None,
                    lane: Lane) -> DriverActionServer:
        return self._goals.serve_goals(name, definition, hooks, owner, lane)

    def send_goal(self, name: str, definition: ActionType, goal_id: str, goal: dict[str, Any],
                  events: GoalEvents, timeout: float) -> DriverGoal:
        return self._goals.send_goal(name, definition, goal_id, goal, events, timeout)


def test_a_driver_with_only_the_required_primitives_is_a_transport() -> None:
    assert MinimalDriver.capabilities == TransportCapabilities(cross_process=False, actions=False, discovery=False,
                                                               discovery_settle_s=1.0)
    received: list[str] = []
    with DriverTransport(MinimalDriver()) as transport:
        assert transport.name == "minimal" and transport.capabilities == MinimalDriver.capabilities
        transport.create_subscription(Topic("words", "String"), received.append, inline=True)
        transport.create_publisher(Topic("words", "String")).publish("hi")
        transport.create_service("echo", lambda request: {"got": request["x"]})
        assert transport.request("echo", {"x": 1}, timeout=1.0) == {"got": 1}
        assert transport.peer_process_options() == {}
        assert received == ["hi"]


def test_the_missing_optional_primitives_say_so() -> None:
    with DriverTransport(MinimalDriver()) as transport:
        with pytest.raises(TransportError, match=r"the minimal transport does not support discovery "
                                                 r"\(its driver MinimalDriver has no discover\(\)\)"):
            transport.discover()
        with pytest.raises(TransportError, match="'minimal' transport has no long-running goals"):
            transport.create_action_server("move", VLA, lambda handle: {})
        with pytest.raises(TransportError, match="'minimal' transport has no long-running goals"):
            transport.send_goal("move", VLA, {"task": "x"})
    # The defaults say the same when a driver is called directly.
    with pytest.raises(TransportError, match="the minimal transport does not support discovery"):
        MinimalDriver().discover(1.0)
    with pytest.raises(TransportError, match="no long-running goals"):
        MinimalDriver().serve_goals("move", VLA, None, None, lambda job: None)  # type: ignore[arg-type]


def test_overriding_the_goal_primitives_turns_actions_on() -> None:
    assert GoalsDriver.capabilities.actions and not GoalsDriver.capabilities.discovery
    with DriverTransport(GoalsDriver()) as transport:
        assert transport.capabilities.actions

        def execute(handle: GoalHandle) -> dict[str, Any]:
            return {"success": True, "message": handle.goal["task"]}

        transport.create_action_server("move", VLA, execute)
        goal = transport.send_goal("move", VLA, {"task": "pick"}, timeout=2.0)
        status, result = goal.result(5.0)
        assert status == GoalStatus.SUCCEEDED and result["message"] == "pick"


def test_one_goal_primitive_alone_keeps_actions_off() -> None:
    class HalfGoals(MinimalDriver):
        serve_goals = GoalsDriver.serve_goals

    assert not HalfGoals.capabilities.actions


def test_discovery_and_its_settle_time_are_data_of_the_driver() -> None:
    class Discovering(MinimalDriver):
        cross_process = True
        discovery_settle_s = 4.0

        def discover(self, timeout: float) -> Any:
            return MemoryDriver().discover(timeout)

    assert Discovering.capabilities == TransportCapabilities(cross_process=True, discovery=True,
                                                             discovery_settle_s=4.0)
    from agents_core.cli.connection import discovery_timeout  # noqa: PLC0415

    with DriverTransport(Discovering()) as transport:
        assert transport.discover().components == []
        assert discovery_timeout(transport, None) == 4.0
        assert discovery_timeout(transport, 0.5) == 0.5


def test_an_entry_point_may_name_the_driver_class(monkeypatch: pytest.MonkeyPatch) -> None:
    class EntryPoint:
        def load(self) -> type[MinimalDriver]:
            return MinimalDriver

    monkeypatch.setattr(registry, "_entry_point_names", lambda: {"minimal": EntryPoint()})
    transport = resolve_transport("minimal")
    try:
        assert isinstance(transport, DriverTransport) and isinstance(transport.driver, MinimalDriver)
    finally:
        transport.close()
